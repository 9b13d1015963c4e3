"""What the studio's test files share (imported by name: pytest puts this folder on sys.path)."""

from __future__ import annotations

import os
from pathlib import Path

DATA = Path(__file__).parent / "data"
# The tests' search: small and short, so that it compiles and runs in seconds.
SEARCH = {"creature": "cart", "controllers": 24, "seconds": 1.0, "seed": 0}
# The tests' MAP-Elites search on the cart: two generations of 32.
QD_SEARCH = {"controllers": 64, "seconds": 1.0, "batch": 32, "seed": 0}


def screenshot(pg, name: str) -> None:
    """Save a screenshot for the README when SANLAB_STUDIO_SCREENSHOTS names a folder."""
    folder = os.environ.get("SANLAB_STUDIO_SCREENSHOTS")
    if folder:
        os.makedirs(folder, exist_ok=True)
        pg.screenshot(path=os.path.join(folder, name))


def ws_url(studio) -> str:
    return studio.url.replace("http://", "ws://") + "ws"


def reply(ws, timeout: float = 60.0) -> dict:
    """The next reply (skipping pushes such as library updates), parsed as strict JSON (a NaN or
    an infinity in it fails)."""
    import json

    def strict(c: str):
        raise ValueError(f"not strict JSON: {c}")

    while True:
        msg = json.loads(ws.recv(timeout=timeout), parse_constant=strict)
        if msg["type"] == "reply":
            return msg
