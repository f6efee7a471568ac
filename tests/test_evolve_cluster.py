"""The Dask backend gives the same run as local evaluation (LocalCluster in this process)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

distributed = pytest.importorskip("dask.distributed")

from bstool.cli import main  # noqa: E402
from bstool.errors import InputError  # noqa: E402
from bstool.evolve.cluster import DaskEvaluator, evaluate_chunk  # noqa: E402
from bstool.evolve.engine import GAParams, new_run, run  # noqa: E402
from bstool.evolve.fitness import ToyEvaluator, ToyFitness  # noqa: E402
from bstool.evolve.problem import Problem  # noqa: E402


@pytest.fixture(scope="module")
def cluster() -> Iterator[distributed.LocalCluster]:
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as c:
        yield c


@dataclass(frozen=True)
class Builds:
    """A factory that counts how often workers build it."""

    count: ClassVar[int] = 0

    def build(self) -> ToyEvaluator:
        Builds.count += 1
        return ToyEvaluator()


def test_chunks_in_order_and_built_once(cluster: distributed.LocalCluster) -> None:
    rng = np.random.default_rng(0)
    seqs = list(rng.integers(0, 16, (13, 5, 5, 6), dtype=np.uint8))
    factory = Builds()
    with distributed.Client(cluster) as client:
        ev = DaskEvaluator(client, factory, chunk=3)  # 5 tasks of ≤3 candidates
        assert ev(seqs) == ToyEvaluator()(seqs)
        assert ev(seqs[:4]) == ToyEvaluator()(seqs[:4])
        assert ev([]) == []
        assert 1 <= Builds.count <= 2  # once per worker thread, not per task
        ev.close()  # the caller's client stays open
        assert client.status == "running"
    assert evaluate_chunk(ToyFitness(), np.stack(seqs[:2])) == ToyEvaluator()(seqs[:2])


def test_same_seed_same_result_local_or_cluster(cluster: distributed.LocalCluster) -> None:
    params = GAParams(pop=6, gens=1, transitions=6, coevol_gens=2, seed=9)
    problem = Problem("ca2ddiff", transitions=6)
    local = run(new_run(problem, params), ToyEvaluator())
    with distributed.Client(cluster) as client:
        remote = run(new_run(problem, params), DaskEvaluator(client, ToyFitness()))
    assert [vars(r) for r in remote.history] == [vars(r) for r in local.history]
    a, b = remote.best_controller(), local.best_controller()
    assert a is not None and b is not None and a.to_json() == b.to_json()


def test_cli_cluster_matches_local(
    cluster: distributed.LocalCluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["nnsin", "--pop", "6", "--gens", "3", "--seed", "2", "--fitness", "toy", "-q"]
    assert main(["evolve", *args, "--out", str(tmp_path / "local")]) == 0
    address = cluster.scheduler_address
    assert main(["evolve", *args, "--out", str(tmp_path / "dask"), "--cluster", address]) == 0
    for name in ("best.json", "history.csv"):
        assert (tmp_path / "local" / name).read_text() == (tmp_path / "dask" / name).read_text()


def test_cluster_unreachable() -> None:
    with pytest.raises(InputError, match="cannot connect to the Dask scheduler at tcp://"):
        DaskEvaluator("tcp://127.0.0.1:1", ToyFitness(), timeout=0.5)


def test_a_cluster_without_workers_says_so_once_and_keeps_waiting() -> None:
    """Every worker gone: after the notice delay the batch says so once, keeps waiting, and
    finishes with the same result when a worker comes back (issue 28 §5)."""
    import threading
    import time

    seqs = list(np.random.default_rng(1).integers(0, 16, (4, 5, 5, 6), dtype=np.uint8))
    told: list[str] = []
    with (
        distributed.LocalCluster(
            n_workers=0, threads_per_worker=1, processes=False, dashboard_address=None
        ) as empty,
        distributed.Client(empty) as client,
    ):
        ev = DaskEvaluator(
            client, ToyFitness(), notify=told.append, no_worker_notice_s=0.5, poll_s=0.1
        )
        out: list[list[float]] = []
        worker = threading.Thread(target=lambda: out.append(ev(seqs)))
        worker.start()
        deadline = time.monotonic() + 30
        while not told and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.5)  # still waiting, and said only once
        assert len(told) == 1 and worker.is_alive() and not out
        assert told[0].startswith("no Dask workers connected to ") and "waiting" in told[0]
        empty.scale(1)
        worker.join(timeout=60)
        assert out == [ToyEvaluator()(seqs)] and len(told) == 1
