"""Creature files: the built-ins shipped in ``sanlab/creature/builtin/``, and loading a creature
by built-in name or by path (the format itself is read by ``loader.loads``)."""

from __future__ import annotations

import os
import stat
from importlib import resources
from pathlib import Path

from ._checks import CreatureError, printable
from .free import Design
from .loader import loads, loads_design
from .spec import MAX_FILE_BYTES, Creature

__all__ = ["NotRegularFile", "TooLarge", "builtin_names", "load", "load_design", "load_file", "read_regular_file", "read_source"]


def _builtin_dir():
    return resources.files("sanlab.creature").joinpath("builtin")


def builtin_names() -> list[str]:
    """Sorted names of the built-in creatures: the stems of ``sanlab/creature/builtin/*.toml``."""
    return sorted(
        p.name[: -len(".toml")] for p in _builtin_dir().iterdir() if p.name.endswith(".toml")
    )


def read_source(name_or_path: str | Path) -> tuple[str, str]:
    """(file text, where it came from): a resolved path, or ``builtin:NAME`` for a built-in.

    Raises :class:`CreatureError` (one line naming the file) for a missing file, a directory, a
    FIFO or device (never read: it could wait for ever), a file over spec.MAX_FILE_BYTES, or
    bytes that are not UTF-8 (a UTF-8 byte-order mark is allowed)."""
    s = str(name_or_path)
    if not s.strip():  # Path("") is the current folder: say what was given
        raise CreatureError(f"expected a creature file or a built-in creature's name {builtin_names()}, got an empty name")
    if isinstance(name_or_path, str) and s in builtin_names():
        return _builtin_dir().joinpath(f"{s}.toml").read_text(encoding="utf-8"), f"builtin:{s}"
    path = Path(name_or_path)
    shown = printable(s)
    try:
        data = read_regular_file(path, MAX_FILE_BYTES)
    except FileNotFoundError:
        hint = "" if path.suffix else f" and no built-in creature of that name{_did_you_mean(s)} {builtin_names()}"
        raise CreatureError(f"{shown}: no such file{hint}") from None
    except NotRegularFile as e:
        raise CreatureError(f"{shown}: expected a creature file, got {e.kind} (give the path of a .toml file)") from None
    except TooLarge:
        raise CreatureError(f"{shown}: expected a creature file of at most {MAX_FILE_BYTES >> 20} MiB, got a larger file") from None
    except OSError as e:
        raise CreatureError(f"{shown}: cannot read ({e.strerror or e})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise CreatureError(f"{shown}: expected a UTF-8 text file, got undecodable bytes at byte {e.start} "
                            "(save it as UTF-8)") from None
    return text, str(path.resolve())


def _did_you_mean(name: str) -> str:
    """"; did you mean 'bounder'?" for a name close to a built-in's ("bouncer"), else ""."""
    import difflib

    close = difflib.get_close_matches(name.lower(), builtin_names(), n=1, cutoff=0.6) if len(name) <= 100 else []
    return f" (did you mean {close[0]!r}?)" if close else ""


class NotRegularFile(OSError):
    """The path names a directory, FIFO, socket or device rather than a regular file."""

    def __init__(self, kind: str):
        super().__init__(kind)
        self.kind = kind


class TooLarge(OSError):
    """The file holds more bytes than the reader accepts."""


def file_kind(mode: int) -> str:
    """What a stat mode is, in words ("a directory", "a FIFO (named pipe)", ...)."""
    for test, what in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return what
    return "not a regular file"


def read_regular_file(path: str | os.PathLike, limit: int, head: int | None = None) -> bytes:
    """The bytes of the regular file at ``path``, at most ``limit`` of them (or its first
    ``head`` bytes, whatever its size).

    Opens without blocking and checks the opened file itself, so a FIFO or a device is refused
    (:class:`NotRegularFile`) rather than read, which could wait for ever; :class:`TooLarge` past
    ``limit`` bytes; other OSErrors as raised."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotRegularFile(file_kind(mode))
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(head if head is not None else limit + 1)
    finally:
        os.close(fd)
    if head is None and len(data) > limit:
        raise TooLarge(f"more than {limit} bytes")
    return data


def load_file(path: str | Path) -> Creature:
    """Load a creature from a .toml file; messages name the file as given."""
    text, _ = read_source(Path(path))
    return loads(text, str(path))


def load(name_or_path: str | Path) -> Creature:
    """Load a built-in creature by name (e.g. "cart"), or else a .toml file by path."""
    text, where = read_source(name_or_path)
    return loads(text, where if where.startswith("builtin:") else str(name_or_path))


def load_design(name_or_path: str | Path) -> tuple[Design, Creature]:
    """A creature file's free numbers and couplings (``free.Design``) and its creature at their
    defaults, by built-in name or path (as :func:`load`); raises :class:`CreatureError`."""
    text, where = read_source(name_or_path)
    return loads_design(text, where if where.startswith("builtin:") else str(name_or_path))
