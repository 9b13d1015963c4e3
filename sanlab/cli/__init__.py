"""The ``sanlab`` command line: this module only composes the commands, one module per group.

``creatures`` (check, creatures), ``simulate``, ``search``, ``library`` (runs, show, export,
import), ``modes``, ``tune``, ``design``, ``audit``, ``reproduce``, ``render``, ``mjcf`` (import-mjcf, export-mjcf: MuJoCo
models in and out), ``studio`` (the web studio, an optional extra);
``_common`` holds what they share (``fail``, the options, opening the library, the progress bar).
Heavy imports (the simulator, the drawing libraries, the web stack) stay inside the commands that
need them, so that ``sanlab check`` starts fast.
Every command that reads the gait library refuses a missing ``--db`` file; only those that start
runs (search, import, reproduce, studio) may create it.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from typing import Annotated, Any

import typer

from sanlab import __version__
from sanlab.cli import audit, ceiling, creatures, design, library, mjcf, modes, render, reproduce, search, simulate, studio, tune


def _flag_types_hidden() -> None:
    """Typer 0.2x writes a type after every option in --help, ``<bool>`` after plain flags
    (``--json``, ``--version``, ``--help``), which reads as if they took a value. Flags show none;
    options that take a value keep theirs (``<int>``, ``<str>``)."""
    from typer.core import TyperOption

    shown = TyperOption.display_type_rich
    if getattr(shown, "_sanlab", False):
        return

    def display_type_rich(self, ctx):
        return None if self.is_flag else shown(self, ctx)

    display_type_rich._sanlab = True  # type: ignore[attr-defined]
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]


_flag_types_hidden()


def _plain_usage_arguments() -> None:
    """Typer writes a required argument as ``{name}`` in the usage line, where the help of every
    other command line (and Click's) writes it bare: ``sanlab check [OPTIONS] CREATURE``, and an
    optional one ``[CREATURE]``. (Each argument names its metavar in capitals.)"""
    from typer.core import TyperArgument

    shown = getattr(TyperArgument, "_usage_display_name", None)
    if shown is None or getattr(shown, "_sanlab", False):  # another Typer: leave its usage lines as they are
        return

    def usage(self) -> str:
        name = shown(self)
        return name[1:].replace("}", "", 1) if self.required and name.startswith("{") else name

    usage._sanlab = True  # type: ignore[attr-defined]
    TyperArgument._usage_display_name = usage  # type: ignore[method-assign]


_plain_usage_arguments()

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


_REDELIVER_S = 0.1
_last_signal = [signal.SIGINT]
_pending: list[threading.Timer] = []


def _interrupt(signum, frame) -> None:
    """SIGINT and SIGTERM end a command as Ctrl-C does: stored work kept, a resume hint. The
    kernel is called a batch at a time, so the KeyboardInterrupt is raised between two calls:
    every finished batch or trial is already committed (SQLite rolls back an open transaction),
    and output files appear whole or not at all."""
    _last_signal[0] = signum
    raise KeyboardInterrupt


def _send_again_soon() -> None:
    timer = threading.Timer(_REDELIVER_S, os.kill, (os.getpid(), _last_signal[0]))
    timer.daemon = True
    _pending.append(timer)
    timer.start()


def _redeliver_interrupts(hook):
    """``sys.unraisablehook`` for a command's lifetime. Python drops an exception raised inside a
    garbage-collector callback (a library may register one) or a ``__del__``: a signal that landed there
    would be lost and the command would run on. Such a KeyboardInterrupt is sent again a moment
    later, out of that context; anything else goes to ``hook``."""

    def unraisable(u) -> None:
        if isinstance(u.exc_type, type) and issubclass(u.exc_type, KeyboardInterrupt):
            _send_again_soon()
            return
        hook(u)

    return unraisable


@app.callback()
def main(
    ctx: typer.Context,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print sanlab's version and exit.")] = False,
) -> None:
    """Discover how planar creatures can move with sensor-actuator networks."""
    from sanlab.cli._common import close_libraries

    ctx.call_on_close(close_libraries)
    try:
        previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, _interrupt)}
    except ValueError:  # not the main thread (an embedding application): leave signals alone
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not when SIGINT is ignored
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, _interrupt)
    hook = sys.unraisablehook
    sys.unraisablehook = _redeliver_interrupts(hook)

    def restore() -> None:
        dropped = any(timer.is_alive() for timer in _pending)
        for timer in _pending:
            timer.cancel()
        _pending.clear()
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        sys.unraisablehook = hook
        if dropped:
            # the command finished before the dropped interrupt came round again: its work is
            # stored, but a script that sent the signal must still see the command was stopped
            typer.echo("interrupted as the command ended: its work is complete and stored", err=True)
            raise typer.Exit(130)

    ctx.call_on_close(restore)


app.command()(creatures.check)
app.command()(creatures.creatures)
app.command()(simulate.simulate)
app.command()(search.search)
app.command()(ceiling.ceiling)
app.command()(library.runs)
app.command()(library.show)
app.command()(modes.modes)
app.command("export")(library.export_)
app.command("import")(library.import_)
app.command()(tune.tune)
app.command()(design.design)
app.command()(audit.audit)
app.command()(reproduce.reproduce)
app.command()(render.render)
app.command()(studio.studio)
app.command("import-mjcf")(mjcf.import_mjcf)
app.command("export-mjcf")(mjcf.export_mjcf)



def run() -> None:
    """The ``sanlab`` program: :data:`app`, with a command-line mistake (an unknown option, a value
    out of range) reported as one line on stderr, exit 2, like every other error."""
    # Typer vendors Click and exports only some of its exceptions: find the bases by name.
    bases: dict[str, Any] = {c.__name__: c for c in typer.BadParameter.__mro__}
    usage_error, click_exception = bases["UsageError"], bases["ClickException"]
    try:
        code = app(prog_name="sanlab", standalone_mode=False)
    except usage_error as e:
        ctx = getattr(e, "ctx", None)
        if type(e).__name__ == "NoArgsIsHelpError" and ctx is not None:
            typer.echo(ctx.get_help())
            code = 0
        else:
            name = ctx.command_path if ctx is not None else "sanlab"
            typer.echo(f"{name}: {e.format_message()} (see {name} --help)", err=True)
            code = e.exit_code
    except click_exception as e:
        typer.echo(f"sanlab: {e.format_message()}", err=True)
        code = e.exit_code
    except typer.Abort:
        typer.echo("aborted", err=True)
        code = 130
    sys.exit(code if isinstance(code, int) else 0)


__all__ = ["app", "run"]
