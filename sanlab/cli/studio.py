"""``sanlab studio``: the command's options; everything else lives in ``sanlab.studio`` (the web
stack is the optional ``studio`` extra, imported only when the command runs)."""

from __future__ import annotations

from typing import Annotated

import typer

from sanlab.cli._common import fail


def studio(
    db: Annotated[str, typer.Option("--db", help="Gait library file (SQLite); created if absent (the studio starts runs).", show_default=True)] = "sanlab.db",
    host: Annotated[str, typer.Option(help=("Address to listen on. Any but a loopback address exposes the whole library, and starting runs, to anyone who can "
                                                    "reach the port, without a password (docs/studio.md, \"On a network\")."))] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=0, max=65535, help="Port to listen on (0: any free port).")] = 8765,
    open_browser: Annotated[bool, typer.Option("--open/--no-open", help="Open the studio in a web browser.")] = True,
) -> None:
    """A local web studio over the gait library: browse runs, watch and compare gaits, steer live."""
    try:
        from sanlab.studio.server import serve
        from sanlab.studio.service import StudioError
    except ImportError as e:  # the web stack is an optional extra
        raise fail(f"studio: missing {e.name} (install with: pip install 'sanlab[studio]')") from None
    try:
        serve(db, host, port, open_browser, echo=typer.echo)
    except StudioError as e:
        raise fail(str(e)) from None
    except OSError as e:
        raise fail(f"studio: cannot listen on {host}:{port}: {e.strerror or e}") from None
