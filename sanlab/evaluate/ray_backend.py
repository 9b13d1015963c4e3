"""``--backend ray``: evaluations on the workers of a Ray cluster (https://www.ray.io).

The driver process connects to a cluster (``address="auto"`` or ``"ray://HOST:PORT"``; none
given: it starts a local one for itself), starts one worker actor per CPU of the cluster (or
``workers``), hands each the evaluator once (the creature's tables: nothing is compiled) and
keeps two requests per worker in flight, so that no worker waits for the driver. Requests and scores are small NumPy arrays; the
gait library stays on the driver's machine and only the driver writes it.

Faults: the actors are restartable and their tasks retried (Ray's ``max_restarts`` and
``max_task_retries``), so a worker process that dies mid-batch is restarted and its batches are
sent again; every evaluation is a pure function of its request, so a batch run twice gives the
same scores, and the driver takes each batch's scores exactly once. A driver killed with SIGKILL
resumes from the library as with the local backend.

Each worker runs the kernel on one thread per CPU it holds (one by default), and a controller's
scores do not depend on the batch it is in or on the number of threads, so a run gives the same
results, bit for bit, locally or on any number of workers.
"""

from __future__ import annotations

import logging
import os
from typing import Any

from sanlab.evaluate.evaluator import Evaluator, Request
from sanlab.evaluate.records import ScoreBatch

INSTALL_HINT = "--backend ray needs Ray: pip install 'sanlab[cluster]'"
IN_FLIGHT_PER_WORKER = 2


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise ImportError(INSTALL_HINT) from None
    return ray


class _Worker:
    """One Ray actor: an evaluator in its own process."""

    def __init__(self, evaluator: Evaluator):
        ray = _ray()
        cpus = int(ray.get_runtime_context().get_assigned_resources().get("CPU", 1)) or 1
        # the kernel's OpenMP threads: one per CPU the worker holds (read when the kernel loads,
        # at the first evaluation), unless Ray or the user set them
        os.environ.setdefault("OMP_NUM_THREADS", str(cpus))
        self.evaluator = evaluator

    def pid(self) -> int:
        return os.getpid()

    def evaluate(self, request: Request) -> ScoreBatch:
        return self.evaluator.evaluate(request)


class RayBackend:
    """See the module docstring. address: "auto", "ray://HOST:PORT", or None (a local cluster
    started for this process, stopped by :meth:`close`). workers: actors to start (default:
    the cluster's CPUs)."""

    def __init__(self, address: str | None = None, workers: int | None = None):
        self._ray = _ray()
        self.address = address
        self.workers = workers
        self.actors: list[Any] = []
        self._refs: dict[Any, tuple[int, int]] = {}  # in flight: object ref -> (ticket, actor)
        self._load: list[int] = []
        self._tickets = 0
        self._pids: list[int] = []
        self._started_ray = False

    @property
    def slots(self) -> int:
        return IN_FLIGHT_PER_WORKER * max(1, len(self.actors))

    def start(self, evaluator: Evaluator) -> None:
        ray = self._ray
        if not ray.is_initialized():
            ray.init(address=self.address, include_dashboard=False, log_to_driver=False,
                     logging_level=logging.WARNING)
            self._started_ray = self.address is None
        n = self.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        actor = ray.remote(num_cpus=1, max_restarts=-1, max_task_retries=-1)(_Worker)
        self.actors = [actor.remote(evaluator) for _ in range(n)]
        self._load = [0] * n
        self._pids = ray.get([a.pid.remote() for a in self.actors])  # also waits for every worker to start

    def submit(self, request: Request) -> int:
        self._tickets += 1
        a = min(range(len(self.actors)), key=lambda i: self._load[i])
        self._load[a] += 1
        self._refs[self.actors[a].evaluate.remote(request)] = (self._tickets, a)
        return self._tickets

    def next(self) -> tuple[int, ScoreBatch]:
        ready, _ = self._ray.wait(list(self._refs), num_returns=1)
        ticket, a = self._refs.pop(ready[0])
        self._load[a] -= 1
        return ticket, self._ray.get(ready[0])

    def describe(self) -> str:
        where = self.address or "local cluster"
        n = len(self.actors) or self.workers
        return f"ray ({where}{f', {n} workers' if n else ''})"

    def pids(self) -> list[int]:
        """The worker processes' ids as started (to watch them, or to test what happens when one
        dies); a restarted worker has a new one."""
        return list(self._pids)

    def close(self) -> None:
        for a in self.actors:
            self._ray.kill(a)
        self.actors, self._refs, self._load = [], {}, []
        if self._started_ray:
            self._ray.shutdown()
            self._started_ray = False
