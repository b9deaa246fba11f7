"""The ``hound-id`` command line: one Typer sub-app per subpackage, no physics here.

Only this package prints or exits. Library errors (:class:`HoundIdError`) become one
line on stderr and exit status 2; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import sys

import typer

from hound_id import __version__
from hound_id.cli import demo as _demo
from hound_id.cli import dyno as _dyno
from hound_id.cli import export as _export
from hound_id.cli import fit_current as _fit_current
from hound_id.cli import fleet as _fleet
from hound_id.cli import foot as _foot
from hound_id.cli import mor as _mor
from hound_id.errors import HoundIdError

app = typer.Typer(
    name="hound-id",
    help="Identify and design the actuators of fast legged robots.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)
app.command("mor", no_args_is_help=True)(_mor.mor)
app.command("saturate", no_args_is_help=True)(_mor.saturate)
app.command("fit-current", no_args_is_help=True)(_fit_current.fit_current)
app.command("effects")(_fit_current.effects)
app.command("fleet", no_args_is_help=True)(_fleet.fleet)
app.add_typer(_dyno.app, name="dyno")
app.command("foot")(_foot.foot)
app.command("export", no_args_is_help=True)(_export.export)
app.command("demo")(_demo.demo)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"hound-id {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version."),
) -> None:
    """Identify and design the actuators of fast legged robots."""


def main(argv: list[str] | None = None) -> None:
    """Console entry point: every error, Typer's own usage errors included, is one line and exit 2.

    Args:
        argv: Arguments without the program name (``sys.argv[1:]`` when None).
    """
    try:
        code = app(args=argv, prog_name="hound-id", standalone_mode=False)
    except HoundIdError as err:
        print(f"hound-id: error: {err}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("hound-id: interrupted", file=sys.stderr)
        sys.exit(130)
    except MemoryError:  # a file far larger than this machine's memory (a log padded with gigabytes of NULs)
        print(
            "hound-id: error: out of memory: an input is too large for this machine's memory; check the input files "
            "(a log padded by a crash, a wrong file) or use a smaller --window",
            file=sys.stderr,
        )
        sys.exit(2)
    except Exception as err:
        # click's exceptions, by name: Typer vendors click from 0.16 on, earlier releases import it
        kinds = {kind.__name__ for kind in type(err).__mro__}
        if "NoArgsIsHelpError" in kinds:  # a bare command: its help, as before
            err.show()  # type: ignore[attr-defined]
            sys.exit(2)
        if "UsageError" in kinds:
            command = _command_path(sys.argv[1:] if argv is None else argv)
            message = err.format_message().replace("\n", " ").rstrip(".")  # type: ignore[attr-defined]
            if command == "hound-id fit-current" and "extra argument" in message:
                message += "; fit-current takes one log: to fit many and compare them, run 'hound-id fleet LOG...'"
            print(f"hound-id: error: {command}: {message}; see '{command} --help'", file=sys.stderr)
            sys.exit(2)
        if "ClickException" in kinds:
            print(f"hound-id: error: {err.format_message()}", file=sys.stderr)  # type: ignore[attr-defined]
            sys.exit(int(getattr(err, "exit_code", 1)))
        if "Abort" in kinds:
            print("hound-id: aborted", file=sys.stderr)
            sys.exit(1)
        raise
    if isinstance(code, int) and code:  # typer.Exit(code) inside a command; 130 on Ctrl-C
        if code == 130:
            print("hound-id: interrupted", file=sys.stderr)
        sys.exit(code)


def run() -> None:
    """Process entry point (the ``hound-id`` script, ``python -m hound_id``): :func:`main`, and on bad input (exit 2)
    or Ctrl-C (exit 130) the process ends at once, its one line flushed, without the interpreter's teardown: nothing
    is left to write (outputs are renamed into place or not at all, the recorder has synced its rows), and a native
    reader thread torn down at exit once turned that exit into an abort (exit 134: "terminate called without an
    active exception") about one run in fifteen under load."""
    import os

    try:
        main()
    except SystemExit as stop:
        if stop.code in (2, 130):  # bad input, or Ctrl-C: the one line is out, nothing is left to do
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(stop.code)
        raise


def _command_path(argv: list[str]) -> str:
    """``hound-id dyno plan`` from the arguments: the words that name (sub-)commands."""
    import typer.main

    command: object = typer.main.get_command(app)
    words = ["hound-id"]
    for token in argv:
        commands = getattr(command, "commands", None)
        if not isinstance(commands, dict) or token not in commands:
            break
        command = commands[token]
        words.append(token)
    return " ".join(words)
