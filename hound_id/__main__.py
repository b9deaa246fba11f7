from hound_id.entry import run

run()
