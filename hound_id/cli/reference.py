"""The Click command behind the Typer app, for the manual's generated command-line reference (mkdocs-click reads
``command``); nothing else imports it."""

import typer.main

from hound_id.cli import app

#: ``hound-id`` as a Click group: every command and option with its help, as ``--help`` prints it.
command = typer.main.get_command(app)
