"""Paper §5 experiments on small runs: mobility, rotation, extrapolation, path shape."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bstool.cli import main
from bstool.controllers import Controller, make_controller, save_controller
from bstool.controllers.reference import nn_initial_reference
from bstool.errors import InputError
from bstool.experiments.extrapolate import reinit_states
from bstool.experiments.mobility import (
    _draw_subsets,
    distances_with,
    mobility,
    random_failures,
    single_failures,
)
from bstool.experiments.paths import distance_curve, heading_deg, path_shape, wrap_deg
from bstool.experiments.rotation import choose_rotation, rotate_controller, rotate_states
from bstool.robot import RobotSpec
from bstool.sim.simulator import Simulator

T = 3  # the model is exactly n-fold symmetric over the first transitions


def nn_controller(seed: int = 3) -> Controller:
    """A random nnsin controller whose module 1 of every leg has no input (X = 0, θ = 0):
    its state is 8 (the tie between 7 and 8 rounds up) at every step, R^0 included."""
    rng = np.random.default_rng(seed)
    w = np.triu(rng.integers(0, 2, (5, 6, 6)), 1)
    w[:, 0, 1] = 0
    leads = rng.integers(0, 16, 5)
    init = nn_initial_reference("nnsin", leads.tolist(), w.tolist(), 16)
    return make_controller("nnsin", init, weights=w, max_trans=30)


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(RobotSpec())


def test_mobility_formula() -> None:
    assert mobility(0.5, 2.0) == 25.0
    assert math.isnan(mobility(0.3, 0.0))


def test_failing_a_module_that_never_changes_keeps_full_mobility(sim: Simulator) -> None:
    c = nn_controller()
    states = c.states(T)
    assert (states[:, :, 1] == 8).all()
    result = single_failures(c, distances_with(sim), T)
    table = result.table
    assert table.shape == (5, 6)
    assert np.all(table[:, 1] == 100.0)  # identical runs, exactly
    assert result.count_at_least(100.0) >= 5
    assert result.count_at_least(80.0) >= result.count_at_least(100.0)
    assert result.to_json()["keep_100"] == result.count_at_least(100.0)


def test_random_failures_are_distinct_and_reproducible(sim: Simulator) -> None:
    subsets = _draw_subsets(30, 3, 20, np.random.default_rng(1))
    assert len(set(subsets)) == 20 and all(len(set(s)) == 3 for s in subsets)
    assert _draw_subsets(30, 3, 20, np.random.default_rng(1)) == subsets
    assert len(_draw_subsets(5, 4, 100, np.random.default_rng(0))) == 5  # all C(5,4)
    c = nn_controller()
    calls: list[int] = []

    def fake(seqs):  # type: ignore[no-untyped-def]
        calls.append(len(seqs))
        return [float(s.sum()) for s in seqs]

    runs = random_failures(c, fake, T, k=2, samples=4, seed=7)
    assert calls == [5] and len(runs) == 4
    assert all(len(r.failed) == 2 for r in runs)
    with pytest.raises(InputError, match="--k"):
        random_failures(c, fake, T, k=31, samples=1)


def test_rotated_controller_walks_the_rotated_path(sim: Simulator) -> None:
    c = nn_controller()
    base = sim.run(c.states(T))
    rotated = rotate_controller(c, 2)
    assert np.array_equal(rotated.states(T), rotate_states(c.states(T), 2))
    turned = sim.run(rotated.states(T))
    a = 2 * 2 * math.pi / 5
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    expected = (base.path - base.path[0]) @ rot.T
    got = turned.path - turned.path[0]
    assert np.abs(got - expected).max() <= 1e-4 * max(base.distance, 1e-3)
    assert abs(wrap_deg(heading_deg(turned.path) - heading_deg(base.path) - 144.0)) < 0.1


def test_choose_rotation() -> None:
    choice = choose_rotation(10.0, 90.0, 5)
    assert choice.legs == 1 and choice.predicted == pytest.approx(82.0)
    assert choice.residual == pytest.approx(8.0)
    assert choose_rotation(10.0, -60.0, 5).legs == 4  # 10 + 288 = 298 = -62
    assert wrap_deg(190.0) == -170.0 and wrap_deg(-180.0) == 180.0


def test_reinit_restarts_the_states_every_n() -> None:
    c = nn_controller()
    plain = c.states(25)
    again = reinit_states(c, 25, 10)
    assert again.shape == plain.shape
    assert np.array_equal(again[:11], plain[:11])
    assert np.array_equal(again[11:22], plain[:11])
    assert np.array_equal(again[22:], plain[:4])
    with pytest.raises(InputError):
        reinit_states(c, 10, 0)


def test_path_shape_of_a_zigzag() -> None:
    path = np.array([[0, 0], [1, 1], [2, -1], [3, 1], [4, 0]], dtype=float)
    s = path_shape(path)
    assert s.distance == 4 and s.max_deviation == 1
    assert s.sway == pytest.approx((1 + 2 + 2 + 1) / 4)
    assert s.length == pytest.approx(2 * math.sqrt(2) + 2 * math.sqrt(5))
    assert s.heading == 0
    assert distance_curve(path).tolist() == pytest.approx(
        [0, math.sqrt(2), math.sqrt(5), math.sqrt(10), 4]
    )


@pytest.fixture()
def controller_file(tmp_path: Path) -> Path:
    path = tmp_path / "nn.json"
    save_controller(nn_controller(), path)
    return path


def _png(path: Path) -> tuple[int, ...]:
    import matplotlib.image

    return tuple(matplotlib.image.imread(path).shape)


def test_faults_cli(
    controller_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "fig17.png"
    assert (
        main(["faults", str(controller_file), "-T", "2", "--json", "--plot", str(png), "-q"]) == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert len(out["runs"]) == 30 and out["modules"] == 30
    assert all(row[1] == 100.0 for row in out["mobility"])
    assert _png(png)[2] in (3, 4)
    assert (
        main(["faults", str(controller_file), "-T", "2", "--k", "2", "--samples", "3", "-q"]) == 0
    )
    assert "median" in capsys.readouterr().out


def test_extrapolate_and_rotate_and_paths_cli(
    controller_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "fig19.png"
    args = ["extrapolate", str(controller_file), "-T", "6", "--reinit-every", "3", "--json"]
    assert main([*args, "--plot", str(png)]) == 0
    curves = json.loads(capsys.readouterr().out)["curves"]
    assert set(curves) == {"plain", "reinit every 3"} and len(curves["plain"]) == 7
    assert curves["plain"][:4] == curves["reinit every 3"][:4]
    assert _png(png)[0] > 100

    out = tmp_path / "turned.json"
    assert (
        main(["rotate", str(controller_file), "--legs", "1", "-o", str(out), "-T", "3", "--json"])
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert abs(report["measured_minus_predicted"]) < 0.1
    assert (
        json.loads(out.read_text())["initial_states"][1]
        == nn_controller().initial_states[0].tolist()
    )
    assert main(["rotate", str(controller_file), "-o", str(out)]) == 2  # neither option

    png2 = tmp_path / "fig18.png"
    assert main(["paths", str(controller_file), str(out), "-T", "3", "--plot", str(png2)]) == 0
    assert "sway" in capsys.readouterr().out and _png(png2)[0] > 100


def test_bad_controller_file_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{nope")
    assert main(["faults", str(bad)]) == 2
    assert "malformed JSON" in capsys.readouterr().err
    assert main(["faults", str(tmp_path / "missing.json")]) == 2


def test_report_from_a_run_directory_and_a_controller(
    controller_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run-nnsin"
    run.mkdir()
    save_controller(nn_controller(), run / "best.json")
    (run / "history.csv").write_text(
        "generation,best,mean,population,evaluations\n0,0.02,0.01,main,10\n1,0.03,0.015,main,20\n"
    )
    out = tmp_path / "report"
    args = [
        "report",
        str(run),
        str(controller_file),
        "-o",
        str(out),
        "-T",
        "2",
        "--extrapolate",
        "4",
    ]
    assert main([*args, "-q"]) == 0
    html = (out / "index.html").read_text()
    assert "run-nnsin" in html and "nn" in html and "<img" in html
    for png in ("paths.png", "faults.png", "fitness.png", "extrapolate-0.png"):
        assert _png(out / png)[0] > 100
    data = json.loads((out / "report.json").read_text())
    assert [e["name"] for e in data["entries"]] == ["run-nnsin", "nn"]
    assert data["entries"][0]["faults"]["modules"] == 30
    assert len(data["entries"][0]["extrapolation"]["plain"]) == 5
    # a bad input leaves the old report untouched
    assert main(["report", str(tmp_path / "nope"), "-o", str(out), "-q"]) == 2
    assert (out / "index.html").read_text() == html


def test_report_multi_failure_curves(controller_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    inputs = [str(controller_file), str(controller_file)]  # two entries: the loop runs twice
    args = ["report", *inputs, "-o", str(out), "-T", "2", "--extrapolate", "3"]
    assert main([*args, "--multi-failures", "2", "-q"]) == 0
    assert _png(out / "multi.png")[0] > 100
    data = json.loads((out / "report.json").read_text())
    assert data["multi_k"] == ["1", "2", "3", "4", "5"]
    by_k = data["entries"][1]["multi_failures"]
    assert {k: v["n"] for k, v in by_k.items()} == {str(k): 2.0 for k in range(1, 6)}
    for stats in by_k.values():  # medians are real M_D values, within the run's extremes
        assert stats["min"] <= stats["median"] <= stats["max"]
    assert "Several modules failed at once" in (out / "index.html").read_text()


def test_fitness_plot_puts_parasites_on_their_own_axis(tmp_path: Path) -> None:
    from bstool.evolve.engine import HistoryRow
    from bstool.experiments.plots import plot_fitness

    rows = [
        HistoryRow(0, 0.1, 0.05, "host", 4),
        HistoryRow(0, 0.4, 0.2, "parasite", 0),
        HistoryRow(1, 0.2, 0.1, "host", 8),
        HistoryRow(1, 0.5, 0.3, "parasite", 0),
    ]
    for name in ("fit.png", "fit.svg"):
        plot_fitness(tmp_path / name, {"run": rows})
    assert _png(tmp_path / "fit.png")[0] > 100
    assert (tmp_path / "fit.svg").read_text().lstrip().startswith("<?xml")


def test_report_has_the_sensitivity_section(controller_file: Path, tmp_path: Path) -> None:
    """`bstool report` measures how far each gait transfers, as `bstool sensitivity` does: the
    same robots for every controller; --sensitivity 0 skips it."""
    from bstool.experiments.sensitivity import design
    from bstool.robot.robotfile import Robot

    out = tmp_path / "report"
    args = ["report", str(controller_file), "-o", str(out), "-T", "2", "--extrapolate", "3", "-q"]
    assert main([*args, "--sensitivity", "2", "--sensitivity-points", "2"]) == 0
    data = json.loads((out / "report.json").read_text())
    sens = data["entries"][0]["sensitivity"]
    plan = design(Robot(), points=2, samples=2, seed=0)
    assert len(sens["joint"]) == 2 and set(sens["sweeps"]) == set(plan.sweeps)
    assert min(sens["joint"]) == sens["worst"] and sens["kept"] == sens["mean"] / sens["nominal"]
    assert "How far each gait transfers" in (out / "index.html").read_text()
    assert _png(out / "sensitivity.png")[0] > 100
    assert sens["intervals"] is None  # 2 robots: too few for an interval of the 10th percentile
    assert main([*args, "--sensitivity", "10", "--sensitivity-points", "2", "--force"]) == 0
    ten = json.loads((out / "report.json").read_text())["entries"][0]["sensitivity"]
    low, high = ten["intervals"]["p10"]
    cell = f"{ten['p10'] * 100:.2f} cm [{low * 100:.1f}, {high * 100:.1f}]"
    assert cell in (out / "index.html").read_text()
    assert main([*args, "--sensitivity", "0", "--force"]) == 0
    assert json.loads((out / "report.json").read_text())["entries"][0]["sensitivity"] is None
