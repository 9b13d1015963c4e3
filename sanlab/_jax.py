"""JAX set-up behind :func:`sanlab.configure` (see there): never run on import.

Done once per process, before JAX creates its CPU backend: split the host into one XLA device
per core (JAX otherwise runs a batch on one core), allow float64 on request, and turn on the
persistent compilation cache so that a second run of the same creature starts in about a second.
"""

from __future__ import annotations

import os
from pathlib import Path

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
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" not in flags:
        n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={max(1, n or 1)}".strip()
    import jax

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
