"""Evaluate on a Dask distributed cluster (optional extra ``bstool[cluster]``).

Each task carries a batch of state sequences plus the evaluator *factory* (a small frozen
dataclass); a worker thread builds the evaluator (the MuJoCo model) the first time it sees a
factory and keeps it for every later task. Results come back in order, and fitness depends
only on the sequence, so the cluster never changes a run's result.
"""

from __future__ import annotations

import math
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bstool.errors import InputError
from bstool.evolve.fitness import Evaluator, EvaluatorFactory

_LOCAL = threading.local()


def evaluate_chunk(factory: EvaluatorFactory, chunk: np.ndarray, robot: Any = None) -> list[float]:
    """Task body, run on a worker: build (once per worker thread) and evaluate (on ``robot``,
    sent as task data: the evaluator cached per factory never holds a draw)."""
    built: dict[Any, Evaluator] = getattr(_LOCAL, "built", None) or {}
    _LOCAL.built = built
    if factory not in built:
        built[factory] = factory.build()
    ev = built[factory]
    return [float(x) for x in (ev(list(chunk)) if robot is None else ev(list(chunk), robot=robot))]


#: seconds without a worker before a waiting batch says so (once per outage)
NO_WORKER_NOTICE_S = 30.0


def _address(client: Any) -> str:
    scheduler = getattr(client, "scheduler", None)
    return str(getattr(scheduler, "address", "the Dask scheduler"))


def _warn(message: str) -> None:
    warnings.warn(message, RuntimeWarning, stacklevel=3)


class DaskEvaluator:
    """An evaluator that spreads each batch over the cluster at ``address`` (or a Client).

    A batch waits for as long as it takes (a worker that comes back finishes it, with the same
    result), but after ``no_worker_notice_s`` with no worker connected it tells ``notify``
    once (default: a ``RuntimeWarning``), so a run never waits for ever without a word.
    """

    def __init__(
        self,
        address: Any,
        factory: EvaluatorFactory,
        chunk: int | None = None,
        timeout: float = 20.0,
        *,
        notify: Callable[[str], None] | None = None,
        no_worker_notice_s: float = NO_WORKER_NOTICE_S,
        poll_s: float = 1.0,
    ) -> None:
        try:
            from dask.distributed import Client
        except ImportError:
            raise InputError(
                "--cluster needs Dask distributed, which is not installed",
                hint="pip install 'bstool[cluster]'",
            ) from None
        if isinstance(address, Client):
            self.client = address
            self._own = False
        else:
            try:
                self.client = Client(address, timeout=f"{timeout}s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(
                    f"cannot connect to the Dask scheduler at {address}: {exc}",
                    hint="start one with `dask scheduler` and workers with `dask worker ADDRESS`",
                ) from None
            self._own = True
        self.factory = factory
        self.chunk = chunk
        self.address = str(address) if isinstance(address, str) else _address(self.client)
        self.notify = notify or _warn
        self.no_worker_notice_s = no_worker_notice_s
        self.poll_s = poll_s
        self._alone_since: float | None = None  # when the last worker left (None: some are here)
        self._told = False

    def _chunk_size(self, count: int) -> int:
        if self.chunk:
            return self.chunk
        threads = max(1, sum(self.client.nthreads().values()))
        return max(1, math.ceil(count / (2 * threads)))  # two tasks per thread: some balance

    def __call__(self, sequences: Sequence[np.ndarray], robot: Any = None) -> list[float]:
        if not sequences:
            return []
        arr = np.stack([np.asarray(s, dtype=np.uint8) for s in sequences])
        size = self._chunk_size(len(arr))
        chunks = [arr[i : i + size] for i in range(0, len(arr), size)]
        n = len(chunks)
        if isinstance(robot, list | tuple):  # one robot per sequence: chunked alike
            robots: list[Any] = [list(robot[i : i + size]) for i in range(0, len(arr), size)]
        else:
            robots = [robot] * n
        futures = self.client.map(evaluate_chunk, [self.factory] * n, chunks, robots, pure=False)
        self._wait(futures)
        results = self.client.gather(futures)
        return [x for part in results for x in part]

    def _wait(self, futures: list[Any]) -> None:
        from dask.distributed import wait

        while True:
            try:
                wait(futures, timeout=self.poll_s)
                return
            except TimeoutError:
                self._check_workers()

    def _check_workers(self) -> None:
        """Say once when no worker has been connected for ``no_worker_notice_s``."""
        if self.client.nthreads():
            self._alone_since, self._told = None, False
            return
        now = time.monotonic()
        if self._alone_since is None:
            self._alone_since = now
        if not self._told and now - self._alone_since >= self.no_worker_notice_s:
            self._told = True
            self.notify(
                f"no Dask workers connected to {self.address}; waiting (start one with "
                f"`dask worker {self.address}`)"
            )

    def close(self) -> None:
        if self._own:
            self.client.close()
