from hound_id.cli import run

run()
