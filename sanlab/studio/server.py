"""Running the studio: in the foreground (`sanlab studio`) or in a background thread (tests).

The server is uvicorn. It listens on 127.0.0.1 unless another host is asked for; on a loopback
address it also refuses requests addressed to any other host name (see ``app``).
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import threading
import time

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and localhost."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class _NotUtf8(logging.Filter):
    """Drops uvicorn's record of a text frame that is not UTF-8, which carries a traceback
    (uvicorn closes that connection with 1007 and serves on: a client's fault, not the server's),
    and logs one line at INFO on ``sanlab.studio`` instead."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage().startswith("Invalid UTF-8 sequence received from client"):
            logging.getLogger("sanlab.studio").info("closed a WebSocket (1007): a text frame was not UTF-8")
            return False
        return True


_QUIET = _NotUtf8()


class StudioServer:
    """A studio over the library ``db`` on ``host``:``port`` (port 0: any free port).

        with StudioServer("gaits.db", port=0) as s:
            print(s.url)

    ``start`` returns once the socket listens; raises OSError if the port is taken and
    StudioError if ``db`` cannot be a gait library.
    """

    def __init__(self, db: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, poll: float = 1.0,
                 log_level: str = "warning"):
        import uvicorn

        from sanlab.studio.app import MAX_FRAME, create_app
        from sanlab.studio.service import Service

        self.host = host
        self.service = Service(db)
        self.app = create_app(self.service, poll=poll, local_only=is_loopback(host))
        config = uvicorn.Config(self.app, host=host, port=port, log_level=log_level, ws="websockets-sansio",
                                ws_max_size=MAX_FRAME, lifespan="on", timeout_graceful_shutdown=2)
        logging.getLogger("uvicorn.error").addFilter(_QUIET)  # after Config: it configures logging
        self.server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None
        self.port = port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def sockets(self) -> list[socket.socket]:
        return [s for srv in self.server.servers for s in srv.sockets]

    def start(self, timeout: float = 60.0) -> "StudioServer":
        errors: list[BaseException] = []

        def run() -> None:
            try:
                self.server.run()
            except BaseException as e:  # reported to start's caller
                errors.append(e)

        self._thread = threading.Thread(target=run, name="sanlab-studio", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout
        while not self.server.started:
            if errors or not self._thread.is_alive():
                raise OSError(f"the studio did not start on {self.host}:{self.port}"
                              + (f": {errors[0]}" if errors else " (is the port in use?)"))
            if time.monotonic() > deadline:
                raise TimeoutError("the studio did not start in time")
            time.sleep(0.02)
        self.port = self.sockets()[0].getsockname()[1]
        return self

    def stop(self) -> None:
        self.server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=10)

    def __enter__(self) -> "StudioServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def has_display(env=None, platform: str | None = None) -> bool:
    """Whether a web browser opened here could show anything: always on macOS and Windows; on
    Linux and the BSDs only with an X or Wayland display (``DISPLAY``, ``WAYLAND_DISPLAY``) or a
    browser named by ``BROWSER`` (a text browser, or a wrapper that opens one elsewhere). Over
    SSH, in a container or CI there is none, and ``webbrowser`` would start a text browser in
    the terminal the server prints to, or nothing."""
    import os
    import sys

    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    if platform == "darwin" or platform.startswith("win"):
        return True
    return any(env.get(k) for k in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER"))


def serve(db: str, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, open_browser: bool = True,
          echo=print) -> None:
    """Serve the studio in the foreground until Ctrl-C. ``echo`` prints status lines. A browser is
    opened only where :func:`has_display` finds a display; elsewhere the address is the line to use."""
    import webbrowser

    s = StudioServer(db, host, port, log_level="warning")
    if not is_loopback(host):
        echo(f"warning: listening on {host}: anyone who can reach this machine on port {port} can read the "
             "whole gait library, export its gaits, start searches and tunings (which write to it and use "
             "every core) and run live simulations; there is no password")
    s.start()
    echo(f"sanlab studio: {s.url}  (library {s.service.path}; Ctrl-C stops)")
    url = s.url.replace("0.0.0.0", "127.0.0.1").replace("[::]", "[::1]")
    if open_browser and has_display():
        threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
    elif open_browser:
        echo(f"no display here (DISPLAY and WAYLAND_DISPLAY are unset): open {url} in a browser yourself "
             "(over SSH: ssh -L PORT:127.0.0.1:PORT this host); --no-open says this is expected")
    try:
        while s._thread is not None and s._thread.is_alive():
            s._thread.join(0.5)
    except KeyboardInterrupt:
        echo("stopping")
    finally:
        s.stop()
