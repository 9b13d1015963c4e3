"""Where evaluations run: the :class:`Backend` protocol and the local backend.

A driver (``sanlab.search.driver``) hands a backend an evaluator once (:meth:`Backend.start`),
then submits requests and collects their scores as they finish, keeping up to ``slots``
requests in flight. Backends only compute: they never store anything, so whatever runs the
evaluations, the driver stays the only writer of the gait library. Every evaluation is a pure
function of its controller and key, so a backend may finish requests in any order, and may run
a request again (after a worker died), without changing any result.

- :class:`Local` (``--backend local``, the default): this process, the batch spread over this
  machine's cores (``sanlab.sim.rollout``; the kernel has no GPU build).
- ``sanlab.evaluate.ray_backend.RayBackend`` (``--backend ray``): Ray workers on a cluster.
"""

from __future__ import annotations

from typing import Protocol

from sanlab.evaluate.evaluator import Evaluator, Request, describe_devices
from sanlab.evaluate.records import ScoreBatch

BACKENDS = ("local", "ray")


class Backend(Protocol):
    """What a driver calls on a backend."""

    @property
    def slots(self) -> int:
        """How many requests it wants in flight to keep every worker busy."""
        ...

    def start(self, evaluator: Evaluator) -> None:
        """Get ready to evaluate with ``evaluator`` (workers compile it once)."""
        ...

    def submit(self, request: Request) -> int:
        """Queue a request; returns its ticket."""
        ...

    def next(self) -> tuple[int, ScoreBatch]:
        """Wait for a submitted request to finish: (its ticket, its scores), in any order."""
        ...

    def map(self, jobs: list[tuple[Evaluator, Request]], /) -> list[ScoreBatch]:
        """Independent (evaluator, request) pairs evaluated (side by side where it can), their
        scores in the order of ``jobs``; needs no :meth:`start`."""
        ...

    def describe(self) -> str:
        """What the evaluations run on (stored as the run's device), e.g. "2 x cpu (cpu)"."""
        ...

    def close(self) -> None:
        """Release the workers (nothing in flight is kept)."""
        ...


class Local:
    """This process: one request at a time, evaluated when its scores are asked for."""

    slots = 1

    def __init__(self) -> None:
        self._evaluator: Evaluator | None = None
        self._queue: list[tuple[int, Request]] = []
        self._tickets = 0

    def start(self, evaluator: Evaluator) -> None:
        self._evaluator = evaluator

    def submit(self, request: Request) -> int:
        self._tickets += 1
        self._queue.append((self._tickets, request))
        return self._tickets

    def next(self) -> tuple[int, ScoreBatch]:
        if self._evaluator is None:
            raise RuntimeError("backend not started")
        ticket, request = self._queue.pop(0)
        return ticket, self._evaluator.evaluate(request)

    def map(self, jobs: list[tuple[Evaluator, Request]]) -> list[ScoreBatch]:
        return [ev.evaluate(r) for ev, r in jobs]

    def twin(self) -> Local:
        """Another local backend, for another thread."""
        return Local()

    def describe(self) -> str:
        return describe_devices()

    def close(self) -> None:
        self._queue.clear()


def evaluate_all(backend: Backend | None, jobs: list[tuple[Evaluator, Request]]) -> list[ScoreBatch]:
    """``backend.map(jobs)``, or each evaluated here in turn where ``backend`` is None."""
    return [ev.evaluate(r) for ev, r in jobs] if backend is None else backend.map(jobs)


def make_backend(name: str = "local", *, address: str | None = None, workers: int | None = None) -> Backend:
    """The backend called ``name`` ("local" or "ray"). ``address`` (ray: "auto", "ray://HOST:PORT";
    default: a Ray cluster started for this process) and ``workers`` (ray: default one per CPU
    of the cluster) only apply to Ray. Raises ValueError for an unknown name or options that do
    not apply, and ImportError (saying how to install it) when Ray is missing."""
    if name == "local":
        if address is not None or workers is not None:
            raise ValueError("--address and --workers apply to --backend ray only")
        return Local()
    if name == "ray":
        from sanlab.evaluate.ray_backend import RayBackend

        return RayBackend(address=address, workers=workers)
    raise ValueError(f"backend: expected one of {list(BACKENDS)}, got {name!r}")
