"""Builds the simulator's kernel (sanlab/sim/_kernel): the one compiled part of sanlab.

Everything else is declared in pyproject.toml. The kernel is C++ over GCC vector types, compiled
once per install for the machine it is installed on (``-march=native``: the widest SIMD the CPU
has), loaded through ctypes by ``sanlab.sim.kernel``. ``-ffp-contract=off`` keeps every
multiply and add a separate IEEE operation, so a creature's trajectory is the same bit for bit on
every lane, thread count and batch size (and agrees with the XLA engine to round-off).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "sanlab.sim._kernel_lib",
            sources=["sanlab/sim/_kernel/kernel.cpp"],
            depends=["sanlab/sim/_kernel/step.h"],
            language="c++",
            extra_compile_args=["-std=c++17", "-O3", "-march=native", "-ffp-contract=off", "-fno-math-errno", "-fopenmp"],
            extra_link_args=["-fopenmp"],
        )
    ]
)
