"""Constants the test modules share (fixtures are in ``conftest.py``)."""

from __future__ import annotations

import signal
import sqlite3
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent  # the checkout (PYTHONPATH for subprocesses)
DATA = Path(__file__).resolve().parent / "data"  # creature files made for the tests
SANLAB = [sys.executable, "-m", "sanlab"]  # the command line, in a fresh process
FPS = 30.0  # frames per second of every replay in the render tests (the rollout compiles once)

# A small valid creature: two jointed segments, a touch and an angle sensor, one servo; the
# creature tests derive their bad files from it.
BASE = """\
[[links]]
name = "L1"
mass = 0.1
shape = "segment"
points = [[0, 0], [0.2, 0]]
angle_deg = 90

[[links]]
name = "L2"
mass = 0.1
shape = "segment"
points = [[0, 0], [0.2, 0]]
parent = "L1"
anchor = [0.2, 0]
angle_deg = -45

[[sensors]]
type = "touch"
link = "L1"
contact = 0

[[sensors]]
type = "angle"
link = "L2"
min_deg = -90
max_deg = 45

[[actuators]]
type = "angular"
joint = "L2"
min_deg = -90
max_deg = 90
ks = 0.002
kd = 0.0002
"""


class TimeLimit(Exception):
    """Raised inside a ``time_limit`` block that ran past its bound."""


@contextmanager
def time_limit(cpu: float = 10.0, wall: float = 120.0):
    """Fail the block (``TimeLimit``) once it has used ``cpu`` seconds of this process's CPU time,
    or ``wall`` seconds of real time (for what waits instead of computing, e.g. a read from a
    FIFO). CPU time barely moves when other work loads the machine, so the bound is not flaky;
    both are far above what the block needs (milliseconds), and catch hangs, not slowness."""

    def expire(signum, frame):
        raise TimeLimit(f"over {cpu:g} s of CPU time" if signum == signal.SIGPROF else f"over {wall:g} s")

    old = signal.signal(signal.SIGPROF, expire), signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_PROF, cpu)
    signal.setitimer(signal.ITIMER_REAL, wall)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGPROF, old[0])
        signal.signal(signal.SIGALRM, old[1])


def one_line_error(message: str, source: str) -> bool:
    """Whether ``message`` is the loader's documented error: one printable line about ``source``."""
    return message.startswith(f"{source}: ") and message.isprintable() and len(message) < 2000


def interruptible() -> None:
    """``preexec_fn`` of a command a test interrupts with SIGINT: a shell that started the test
    suite in the background leaves SIGINT ignored, every child inherits that, and Python then
    installs no KeyboardInterrupt handler (as Unix asks); give the child the default back."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def rows_in(db, table: str = "evaluations") -> int:
    """How many rows ``table`` of the library file ``db`` holds now (0 while it cannot be read):
    what a test polls while a command it will interrupt writes."""
    try:
        with sqlite3.connect(db, timeout=5) as c:
            return c.execute(f"select count(*) from {table}").fetchone()[0]
    except sqlite3.Error:
        return 0


def same_on_one_and_two_threads(code: str, tmp_path: Path) -> None:
    """Run ``code`` (it saves one array to the path in ``sys.argv[1]``) in a fresh process on 1
    and on 2 OpenMP threads, from the checkout, and assert the two arrays are equal bit for bit."""
    import os
    import subprocess

    outs = []
    for threads in ("1", "2"):
        path = tmp_path / f"q{threads}.npy"
        env = dict(os.environ, OMP_NUM_THREADS=threads)
        subprocess.run([sys.executable, "-c", code, str(path)], check=True, env=env, cwd=ROOT)
        outs.append(np.load(path))
    assert np.array_equal(outs[0], outs[1])
