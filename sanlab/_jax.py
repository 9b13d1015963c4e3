"""JAX set-up behind :func:`sanlab.configure` (see there): never run on import.

Done once per process, before JAX creates its CPU backend: split the host into one XLA device
per core (JAX otherwise runs a batch on one core), allow float64 on request, and turn on the
persistent compilation cache so that a second run of the same creature starts in about a second.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import signal
import threading
from pathlib import Path
from typing import Any, Callable

_done = False


def cache_dir() -> Path:
    """Where the persistent compilation cache lives: ``$SANLAB_CACHE/jax``, else
    ``$XDG_CACHE_HOME/sanlab/jax`` (``~/.cache/sanlab/jax``)."""
    root = os.environ.get("SANLAB_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "sanlab"
    )
    return Path(root) / "jax"


def configure() -> None:
    """See :func:`sanlab.configure`."""
    global _done
    if _done:
        return
    with _interrupts_deferred():
        flags = os.environ.get("XLA_FLAGS", "")
        if "xla_force_host_platform_device_count" not in flags:
            n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
            os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={max(1, n or 1)}".strip()
        import jax

        with contextlib.suppress(ImportError):  # a native module JAX loads at the first lowering
            importlib.import_module("jaxlib.mlir.dialects.mhlo")
        jax.config.update("jax_enable_x64", True)
        if os.environ.get("SANLAB_NO_COMPILE_CACHE") != "1":
            path = cache_dir()
            try:
                path.mkdir(parents=True, exist_ok=True)
                jax.config.update("jax_compilation_cache_dir", str(path))
                jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
                jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
            except OSError:
                pass  # a read-only home only costs compile time
        _done = True


@contextlib.contextmanager
def _interrupts_deferred():
    """Hold SIGINT and SIGTERM back from Python handlers while JAX is imported, then deliver them.

    Importing jaxlib runs Python code (enum classes, for one) from inside its native modules'
    initialisation; a KeyboardInterrupt raised there by a handler is a C++ exception nobody
    catches: the process aborts ("terminate called ...", exit 134) or, with the module left half
    built, crashes later (SIGSEGV). Seen when Ctrl-C or SIGTERM reached ``sanlab`` in its first
    second. The native module JAX would load at its first lowering is loaded here too, for the
    same reason. Only signals whose handler is a Python callable are held (a default SIGTERM still
    ends the process at once); outside the main thread nothing can be changed, and nothing is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous: dict[int, Callable[[int, Any], Any]] = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(signum)
        if callable(handler):
            signal.signal(signum, lambda s, _frame: held.append(s))
            previous[signum] = handler
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if held:
        previous[held[0]](held[0], None)  # the handler the signal would have met: for sanlab's CLI, KeyboardInterrupt
