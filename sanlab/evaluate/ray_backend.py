"""``--backend ray``: evaluations on the workers of a Ray cluster (https://www.ray.io).

The driver process connects to a cluster (``address="auto"`` or ``"ray://HOST:PORT"``; none
given: it starts a local one for itself, kept for the process's later runs) and evaluates each
request as Ray *tasks* of one CPU each. The evaluator goes into Ray's object store once
(:meth:`RayBackend.start`, or the first request of :meth:`RayBackend.map` that names it), and each
worker process keeps the evaluators it has used, so a creature's tables are built once a worker.
Requests and scores are small NumPy arrays; the gait library stays on the driver's machine and
only the driver writes it.

The grain is the evaluation batch. A request is split into chunks of at least
:data:`MIN_CHUNK` controllers while fewer than :data:`IN_FLIGHT_PER_WORKER` tasks a worker are in
flight (so one batch of 200 random SANs, or one tuning window of 32 trials, keeps every worker
busy), and the driver keeps ``slots`` requests in flight. A controller's scores do not depend on
the batch it is in or on the worker that ran it, so a run gives the same results, bit for bit,
locally or on any number of workers, however its batches were split.

Faults: a task whose worker process or node dies is run again by Ray (up to :data:`RETRIES`
times) on whatever node is alive; every evaluation is a pure function of its request, so a
chunk run twice gives the same scores, and the driver takes each chunk's scores exactly once. A
driver killed with SIGKILL resumes from the library as with the local backend. An evaluation
that raises on a worker ends the run with one line naming the piece (:class:`WorkerError`), not
a remote traceback.
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import threading
import time
from collections import OrderedDict
from typing import Any

from sanlab.evaluate.evaluator import Evaluator, Request
from sanlab.evaluate.records import ScoreBatch

INSTALL_HINT = "--backend ray needs Ray: pip install 'sanlab[cluster]'"
IN_FLIGHT_PER_WORKER = 2  # tasks a worker: one running, one waiting, so none waits for the driver
MIN_CHUNK = 8  # controllers: a request is never split finer (a task's overhead is ~1 ms)
RETRIES = 5  # a task lost with its worker or node is run again this many times
CACHE = 16  # evaluators a worker process keeps


class WorkerError(RuntimeError):
    """An evaluation raised on a Ray worker: one line naming the piece (a Table 1 row's step, or
    the creature, batch size and first key) and the error, in place of a remote traceback."""


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise ImportError(INSTALL_HINT) from None
    return ray


_CONNECTING = threading.Lock()
_EVALUATORS: OrderedDict[str, Evaluator] = OrderedDict()  # in a worker process: evaluators by token


def _evaluate(token: str, holder: list, request: Request) -> tuple[int, ScoreBatch | None, str]:
    """One task on a worker: (its pid, the scores, "") or (pid, None, the error in one line).
    ``holder``: [the evaluator's object ref], in a list so that Ray hands it over unresolved and
    the evaluator is fetched only by a worker that has not kept it."""
    try:
        ev = _EVALUATORS.get(token)
        if ev is None:
            ev = _ray().get(holder[0])
            _EVALUATORS[token] = ev
            while len(_EVALUATORS) > CACHE:
                _EVALUATORS.popitem(last=False)
        return os.getpid(), ev.evaluate(request), ""
    except Exception as e:  # a remote traceback says nothing the piece and the message do not
        return os.getpid(), None, f"{type(e).__name__}: {e}"


def _piece(evaluator: Evaluator, request: Request, label: str | None) -> str:
    """How an error names the piece: the caller's label (a Table 1 row's step) or the creature,
    then the batch's size and first key."""
    where = label or f"{evaluator.spec.name}"
    first = f", first key {request.keys[0]}" if request.keys else ""
    return f"{where}: a batch of {len(request)}{first}"


class RayBackend:
    """See the module docstring. address: "auto", "ray://HOST:PORT", or None (a local cluster
    started for this process, stopped by :meth:`shutdown` or when the process ends). workers:
    tasks to run at once (default: the cluster's CPUs when it starts). ``label``: named by a
    :class:`WorkerError` (``sanlab reproduce`` sets it to the row and step)."""

    def __init__(self, address: str | None = None, workers: int | None = None):
        self._ray = _ray()
        self.address = address
        self.workers = workers
        self.label: str | None = None
        self._n = 0
        self._task: Any = None
        self._refs: dict[Any, tuple[int, int]] = {}  # in flight: object ref -> (ticket, chunk)
        self._parts: dict[int, list[ScoreBatch | None]] = {}
        self._what: dict[int, str] = {}  # ticket -> the piece, for an error
        self._tickets = 0
        self._pids: dict[int, None] = {}
        self._puts: OrderedDict[str, list] = OrderedDict()  # token -> [object ref]
        self._evaluator: tuple[Evaluator, str, list] | None = None
        self._started_ray = False
        self._alive: tuple[float, int] = (0.0, 0)
        self._inflight = [0]  # tasks in flight, over this backend and its twins (they split by it)
        self._lock = threading.Lock()
        self._twin = False
        self._stopping = threading.Event()  # set by stop(), for this backend and its twins

    @property
    def slots(self) -> int:
        return IN_FLIGHT_PER_WORKER * max(1, self._n or self.workers or 1)

    def connect(self) -> None:
        """Join the cluster (or start one here) and size the pool; done by :meth:`start` and
        :meth:`map`, and once per process."""
        ray = self._ray
        if not self._twin:
            self._stopping.clear()  # a new job on this backend after stop(): it runs again
        with _CONNECTING:  # twins on other threads: one ray.init
            if not ray.is_initialized() and self._twin:
                # the process is ending (Ctrl-C): a row still running stops here, never starts a cluster
                raise WorkerError("the connection to the Ray cluster is closed")
            if not ray.is_initialized():
                # no address: a cluster of this process's own, never one that happens to run here
                ray.init(address=self.address or "local", include_dashboard=False, log_to_driver=False,
                         logging_level=logging.WARNING)
                self._started_ray = self.address is None
        if self._task is None:
            self._n = self.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
            self._task = ray.remote(num_cpus=1, max_retries=RETRIES)(_evaluate)

    def twin(self) -> RayBackend:
        """A backend on the same cluster for another thread of this driver (a row of a table
        made side by side): its own requests, the same connection, and one count of the tasks in
        flight, so that a batch is split only while the whole cluster has room."""
        other = RayBackend(self.address, self.workers)
        other._inflight, other._lock, other._twin, other._stopping = self._inflight, self._lock, True, self._stopping
        return other

    def _put(self, evaluator: Evaluator) -> tuple[str, list]:
        """The evaluator's token (a hash of its pickle: the same evaluator built again, as every
        look of an audit builds its own, is the one a worker kept) and [its object ref]."""
        token = hashlib.sha1(pickle.dumps(evaluator)).hexdigest()
        if token not in self._puts:
            self._puts[token] = [self._ray.put(evaluator)]
            while len(self._puts) > 4 * CACHE:
                self._puts.popitem(last=False)
        return token, self._puts[token]

    def start(self, evaluator: Evaluator) -> None:
        self.connect()
        self._evaluator = (evaluator, *self._put(evaluator))

    def _submit(self, evaluator: Evaluator, token: str, holder: list, request: Request) -> int:
        if not self._ray.is_initialized():  # Ray would start a cluster of its own for the call
            raise WorkerError("the connection to the Ray cluster is closed")
        self._tickets += 1
        t = self._tickets
        with self._lock:
            room = IN_FLIGHT_PER_WORKER * self._n - self._inflight[0]
            k = max(1, min(len(request) // MIN_CHUNK, room))
            self._inflight[0] += k
        bounds = [round(i * len(request) / k) for i in range(k + 1)]
        self._parts[t] = [None] * k
        self._what[t] = _piece(evaluator, request, self.label)
        for c in range(k):
            part = slice(bounds[c], bounds[c + 1])
            sub = Request(request.weights[part], None if request.thetas is None else request.thetas[part],
                          tuple(request.keys[part]), None if request.patterns is None else request.patterns[part])
            self._refs[self._task.remote(token, holder, sub)] = (t, c)
        return t

    def submit(self, request: Request) -> int:
        if self._evaluator is None:
            raise RuntimeError("backend not started")
        return self._submit(*self._evaluator, request)

    def next(self) -> tuple[int, ScoreBatch]:
        while True:
            if self._stopping.is_set():
                raise WorkerError("stopped: the driver is ending")
            ready, _ = self._ray.wait(list(self._refs), num_returns=1, timeout=0.5)
            if not ready:
                continue
            t, c = self._refs.pop(ready[0])
            with self._lock:
                self._inflight[0] -= 1
            try:
                pid, scores, error = self._ray.get(ready[0])
            except self._ray.exceptions.RayError as e:  # lost more often than Ray runs a task again
                said = (str(e).strip().splitlines() or [""])[0]
                raise WorkerError(f"{self._what[t]}: lost with its worker {RETRIES + 1} times "
                                  f"({type(e).__name__}: {said})") from None
            self._pids[pid] = None
            if scores is None:
                raise WorkerError(f"{self._what[t]}: {error}")
            parts = self._parts[t]
            parts[c] = scores
            if all(p is not None for p in parts):
                del self._parts[t]
                del self._what[t]
                return t, ScoreBatch.concat([p for p in parts if p is not None])

    def map(self, jobs: list[tuple[Evaluator, Request]]) -> list[ScoreBatch]:
        """Every (evaluator, request) of ``jobs`` evaluated on the cluster, all in flight at once,
        their scores in the order of ``jobs`` (independent evaluations, such as an audit's nudges)."""
        self.connect()
        tickets = [self._submit(ev, *self._put(ev), r) for ev, r in jobs]
        out: dict[int, ScoreBatch] = {}
        try:
            while len(out) < len(tickets):
                t, scores = self.next()
                out[t] = scores
        except BaseException:
            self._drop()
            raise
        return [out[t] for t in tickets]

    def stop(self) -> None:
        """Make this backend's and its twins' waits end (a :class:`WorkerError` within half a
        second), so that the threads using them stop before the process ends; the backend's
        next :meth:`connect` (its next job) undoes it."""
        self._stopping.set()

    def alive(self) -> int:
        """Workers the cluster can run now: its alive CPUs, at most ``workers`` (asked of Ray at
        most once a second)."""
        now = time.monotonic()
        if now - self._alive[0] >= 1.0 and self._ray.is_initialized():
            cpus = int(self._ray.cluster_resources().get("CPU", 0))
            self._alive = (now, min(cpus, self._n) if self._n else cpus)
        return self._alive[1]

    def describe(self) -> str:
        where = self.address or "local cluster"
        n = self._n or self.workers
        return f"ray ({where}{f', {n} workers' if n else ''})"

    def pids(self) -> list[int]:
        """The worker processes that have returned scores so far, the first first (to watch them,
        or to test what happens when one dies)."""
        return list(self._pids)

    def _drop(self) -> None:
        for ref in self._refs:
            try:
                self._ray.cancel(ref)
            except Exception:  # already finished, or its worker gone: nothing to cancel
                pass
        with self._lock:
            self._inflight[0] -= len(self._refs)
        self._refs, self._parts, self._what = {}, {}, {}

    def close(self) -> None:
        """Forget what is in flight; the connection (and a cluster started here) is kept for
        this process's next run: :meth:`shutdown` ends it."""
        self._drop()
        self._evaluator = None

    def shutdown(self) -> None:
        """:meth:`close`, and stop the Ray cluster this backend started (if it did)."""
        self.close()
        if self._started_ray:
            self._ray.shutdown()
            self._started_ray = False
        self._task, self._n, self._puts = None, 0, OrderedDict()

