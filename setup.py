"""Builds the simulator's kernel (sanlab/sim/_kernel): the one compiled part of sanlab.

Everything else is declared in pyproject.toml. The kernel is C++ over GCC vector types, compiled
once per install for the machine it is installed on (``-march=native``: the widest SIMD the CPU
has), loaded through ctypes by ``sanlab.sim.kernel``. ``-ffp-contract=off`` keeps every
multiply and add a separate IEEE operation, so a creature's trajectory is the same bit for bit on
every lane, thread count and batch size (and agrees with the XLA engine to round-off).
"""

import hashlib
from pathlib import Path

from setuptools import Extension, setup


def kernel_source_hash(folder: Path) -> str:
    """The hash the built kernel carries of the sources it was built from; sanlab.sim.kernel
    computes the same from the installed sources and refuses a library built from others (a
    stale build after a pull that changed the kernel would read its arguments wrongly)."""
    h = hashlib.sha256()
    for f in sorted(folder.glob("*.[hc]*")):
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


setup(
    ext_modules=[
        Extension(
            "sanlab.sim._kernel_lib",
            sources=["sanlab/sim/_kernel/kernel.cpp"],
            depends=sorted(str(p) for p in Path("sanlab/sim/_kernel").glob("*.[hc]*")),  # every source the hash covers
            define_macros=[("SANLAB_KERNEL_SOURCE", '"%s"' % kernel_source_hash(Path("sanlab/sim/_kernel")))],
            language="c++",
            extra_compile_args=["-std=c++17", "-O3", "-march=native", "-ffp-contract=off", "-fno-math-errno", "-fopenmp"],
            extra_link_args=["-fopenmp"],
        )
    ]
)
