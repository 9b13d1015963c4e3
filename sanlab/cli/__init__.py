"""The ``sanlab`` command line: this module only composes the commands, one module per group.

``creatures`` (check, creatures), ``simulate``, ``search``, ``library`` (runs, show, export,
import), ``tune``, ``audit``, ``reproduce``, ``render``, ``studio`` (the web studio, an optional extra);
``_common`` holds what they share (``fail``, the options, opening the library, the progress bar).
Heavy imports (JAX, the drawing libraries, the web stack) stay inside the commands that need them,
so that ``sanlab check`` starts fast; commands that simulate call :func:`sanlab.configure` first.
Every command that reads the gait library refuses a missing ``--db`` file; only those that start
runs (search, import, reproduce, studio) may create it.
"""

from __future__ import annotations

import signal
from typing import Annotated

import typer

from sanlab import __version__
from sanlab.cli import audit, creatures, library, render, reproduce, search, simulate, studio, tune

app = typer.Typer(
    help="Discover how planar creatures can move with sensor-actuator networks.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"sanlab {__version__}")
        raise typer.Exit()


def _terminate(signum, frame) -> None:
    raise KeyboardInterrupt  # SIGTERM ends a command as Ctrl-C does: stored work kept, a resume hint


@app.callback()
def main(
    ctx: typer.Context,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print sanlab's version and exit.")] = False,
) -> None:
    """Discover how planar creatures can move with sensor-actuator networks."""
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread (an embedding application): leave signals alone
        return
    ctx.call_on_close(lambda: signal.signal(signal.SIGTERM, previous))


app.command()(creatures.check)
app.command()(creatures.creatures)
app.command()(simulate.simulate)
app.command()(search.search)
app.command()(library.runs)
app.command()(library.show)
app.command("export")(library.export_)
app.command("import")(library.import_)
app.command()(tune.tune)
app.command()(audit.audit)
app.command()(reproduce.reproduce)
app.command()(render.render)
app.command()(studio.studio)

__all__ = ["app"]
