"""Creature files: the built-ins shipped in ``sanlab/creature/builtin/``, and loading a creature
by built-in name or by path (the format itself is read by ``loader.loads``)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ._checks import CreatureError
from .loader import loads
from .spec import Creature

__all__ = ["builtin_names", "load", "load_file", "read_source"]


def _builtin_dir():
    return resources.files("sanlab.creature").joinpath("builtin")


def builtin_names() -> list[str]:
    """Sorted names of the built-in creatures: the stems of ``sanlab/creature/builtin/*.toml``."""
    return sorted(
        p.name[: -len(".toml")] for p in _builtin_dir().iterdir() if p.name.endswith(".toml")
    )


def read_source(name_or_path: str | Path) -> tuple[str, str]:
    """(file text, where it came from): a resolved path, or ``builtin:NAME`` for a built-in."""
    s = str(name_or_path)
    if isinstance(name_or_path, str) and s in builtin_names():
        return _builtin_dir().joinpath(f"{s}.toml").read_text(encoding="utf-8"), f"builtin:{s}"
    path = Path(name_or_path)
    try:
        return path.read_text(encoding="utf-8"), str(path.resolve())
    except FileNotFoundError:
        hint = "" if path.suffix else f" and no built-in creature of that name {builtin_names()}"
        raise CreatureError(f"{s}: no such file{hint}") from None
    except UnicodeDecodeError:
        raise CreatureError(f"{s}: expected a UTF-8 text file, got undecodable bytes") from None
    except OSError as e:
        raise CreatureError(f"{s}: cannot read ({e.strerror or e})") from None


def load_file(path: str | Path) -> Creature:
    """Load a creature from a .toml file; messages name the file as given."""
    text, _ = read_source(Path(path))
    return loads(text, str(path))


def load(name_or_path: str | Path) -> Creature:
    """Load a built-in creature by name (e.g. "cart"), or else a .toml file by path."""
    text, where = read_source(name_or_path)
    return loads(text, where if where.startswith("builtin:") else str(name_or_path))
