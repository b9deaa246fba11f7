from hound_id.cli import main

main()
