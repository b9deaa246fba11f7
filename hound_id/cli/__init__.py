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
from hound_id.cli import dyno_rig as _dyno_rig
from hound_id.cli import export as _export
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
app.command("fit-current", no_args_is_help=True)(_dyno.fit_current)
app.command("effects")(_dyno.effects)
app.add_typer(_dyno_rig.app, name="dyno")
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


def main() -> None:
    """Console entry point. Typer handles usage errors itself (exit 2); ours are caught here."""
    try:
        app()
    except HoundIdError as err:
        print(f"hound-id: error: {err}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("hound-id: interrupted", file=sys.stderr)
        sys.exit(130)
