"""Traced programs kept on disk, so that a warm start skips JAX's trace as well as XLA's compile.

JAX's persistent compilation cache (turned on by :func:`sanlab.configure`) skips XLA's compile but
not what comes before it: tracing the step's unrolled code (about 11,000 primitives for the
bounder) and lowering it, 0.5-2 s of every fresh process's first rollout (more on a busy machine),
so a replay that simulates in 0.3 s (a 6 s gait at batch 1) started in about 2 s. Here the traced
program is exported (``jax.export``: StableHLO, a stable serialisation) under a digest of
everything that shapes it; a later process deserialises it in milliseconds and XLA's compile is
then a hit in the persistent cache. Every call, the first included, runs the exported program, so
a result never depends on whether its program came from disk.

The key is a SHA-256 of: the sanlab source (every ``.py`` of the package, so an edit can never
load a stale program), the JAX and jaxlib versions, the devices (platform, kind, count), the
program's configuration (controller and observer by class and ``repr``, duration, recording,
flags) and the input tree (its structure, which holds the creature's static structure and spec,
and every leaf's shape and dtype). A configuration whose ``repr`` names a memory address (an
object without a dataclass repr) is not stored: its key would differ in every process.

Why not ``jax.experimental.serialize_executable`` (it skips XLA too): on the CPU an executable
that XLA loaded from the persistent cache serialises into one that fails when called in another
process ("Function ... not found", jaxlib 0.10.2), and whether a compile hit that cache is not
under our control.

Entries live in ``<cache>/programs`` (beside :func:`sanlab._jax.cache_dir`), written atomically;
a file that fails to load is removed and exported again. ``SANLAB_NO_COMPILE_CACHE=1`` turns this
off with the persistent cache. The directory is trimmed to :data:`MAX_BYTES`, oldest first.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import threading
from collections import OrderedDict
from functools import cache
from pathlib import Path
from typing import Any, Callable, NamedTuple

import jax

from sanlab._jax import cache_dir

MAX_BYTES = 1024**3  # the directory's size cap; an entry is 0.1-1 MB for the paper's creatures
_SOURCE: str | None = None
MAX_LOADED = 64  # programs kept in memory, as sim.rollout keeps its traced ones (an LRU: each holds an executable)
_loaded: "OrderedDict[tuple, Any]" = OrderedDict()
_lock = threading.Lock()


def enabled() -> bool:
    return os.environ.get("SANLAB_NO_COMPILE_CACHE") != "1"


def directory() -> Path:
    return cache_dir().parent / "programs"


def source_digest() -> str:
    """SHA-256 of every module of the sanlab package (file names and contents), once a process."""
    global _SOURCE
    if _SOURCE is None:
        root = Path(__file__).resolve().parent.parent
        h = hashlib.sha256()
        for path in sorted(root.rglob("*.py")):
            h.update(str(path.relative_to(root)).encode())
            h.update(path.read_bytes())
        _SOURCE = h.hexdigest()
    return _SOURCE


@cache
def _jaxlib_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("jaxlib")
    except PackageNotFoundError:
        return "?"


def _name(x: Any) -> str:
    return f"{type(x).__module__}.{type(x).__qualname__}:{x!r}"


def key(config: tuple, args: tuple) -> str | None:
    """The digest of a program's configuration and its inputs, or None if it cannot be stable
    across processes (a ``repr`` with a memory address in it)."""
    leaves, tree = jax.tree_util.tree_flatten(args)
    avals = [(tuple(getattr(x, "shape", ())), str(getattr(x, "dtype", type(x).__name__))) for x in leaves]
    devs = jax.devices()
    text = "\n".join([
        source_digest(), jax.__version__, _jaxlib_version(),
        f"{devs[0].platform} {devs[0].device_kind} {len(devs)}",
        *(_name(c) for c in config), repr(tree), repr(avals),
    ])
    if " at 0x" in text:
        return None
    return hashlib.sha256(text.encode()).hexdigest()


def _export(jitted: Callable, args: tuple):
    """(exported program of ``jitted`` at ``args``, taking and giving flat leaves; output tree)."""
    leaves, in_tree = jax.tree_util.tree_flatten(args)
    box = {}

    def flat(*xs):
        out, box["out"] = jax.tree_util.tree_flatten(jitted(*jax.tree_util.tree_unflatten(in_tree, xs)))
        return out

    shardings = [getattr(x, "sharding", None) for x in leaves]
    exported = jax.export.export(jax.jit(flat, in_shardings=shardings))(*leaves)
    return exported, box["out"]


def _store(path: Path, exported, out_tree) -> None:
    blob = pickle.dumps((bytes(exported.serialize()), out_tree), protocol=pickle.HIGHEST_PROTOCOL)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_bytes(blob)
    os.replace(tmp, path)
    _trim(path.parent)


def _trim(folder: Path) -> None:
    entries = []
    for p in folder.glob("*.stablehlo"):
        try:
            s = p.stat()
        except OSError:
            continue
        entries.append((s.st_mtime, s.st_size, p))
    total = sum(e[1] for e in entries)
    for _, size, p in sorted(entries):
        if total <= MAX_BYTES:
            break
        p.unlink(missing_ok=True)
        total -= size


def _load(path: Path):
    blob, out_tree = pickle.loads(path.read_bytes())
    return jax.export.deserialize(bytearray(blob)), out_tree


class _Program(NamedTuple):
    run: Callable  # flat leaves -> flat leaves, compiled on first call (XLA's cache applies)
    out_tree: Any


def call(config: tuple, jitted: Callable, args: tuple) -> Any:
    """``jitted(*args)``, run as the exported program stored for this configuration and these
    inputs (see the module docstring), exported and stored first if there is none.

    config: hashable, the program's configuration (what ``jitted`` was built from); args: the
    program's inputs (placed on their devices, or host arrays for a one-device program). Falls
    back to ``jitted`` itself when the cache is off or the key cannot be stable; a stored file
    that fails to load is replaced."""
    if not enabled():
        return jitted(*args)
    leaves, tree = jax.tree_util.tree_flatten(args)
    mem = (config, tree, tuple((getattr(x, "shape", None), str(getattr(x, "dtype", ""))) for x in leaves))
    with _lock:
        program = _loaded.get(mem)
        if program is None:
            program = _obtain(config, jitted, args)
            _loaded[mem] = program
            while len(_loaded) > MAX_LOADED:
                _loaded.popitem(last=False)
        else:
            _loaded.move_to_end(mem)
    if program is _UNSTABLE:
        return jitted(*args)
    return jax.tree_util.tree_unflatten(program.out_tree, program.run(*leaves))


_UNSTABLE: Any = object()


def _obtain(config: tuple, jitted: Callable, args: tuple):
    digest = key(config, args)
    if digest is None:
        return _UNSTABLE
    path = directory() / f"{digest}.stablehlo"
    found = None
    if path.exists():
        try:
            found = _load(path)
            os.utime(path)  # recently used: trimmed last
        except Exception:  # a truncated file, or one from an incompatible build: export again
            path.unlink(missing_ok=True)
    if found is not None:
        exported, out_tree = found
    else:
        exported, out_tree = _export(jitted, args)
        try:
            _store(path, exported, out_tree)
        except OSError:
            pass  # a read-only or full disk only costs the next start its trace
    return _Program(jax.jit(exported.call), out_tree)
