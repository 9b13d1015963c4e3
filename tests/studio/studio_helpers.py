"""What the studio's test files share (imported by name: pytest puts this folder on sys.path)."""

from __future__ import annotations

import os
from pathlib import Path

DATA = Path(__file__).parent / "data"
# The tests' search: small and short, so that it compiles and runs in seconds.
SEARCH = {"creature": "cart", "controllers": 24, "seconds": 1.0, "seed": 0}


def screenshot(pg, name: str) -> None:
    """Save a screenshot for the README when SANLAB_STUDIO_SCREENSHOTS names a folder."""
    folder = os.environ.get("SANLAB_STUDIO_SCREENSHOTS")
    if folder:
        os.makedirs(folder, exist_ok=True)
        pg.screenshot(path=os.path.join(folder, name))
