"""``bstool evolve --randomize``: common random numbers, fresh draws each generation, the elite
re-scored, validation, best.json, resume identical, and every scoring mode and backend."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bstool.cli import main
from bstool.evolve import driver
from bstool.evolve import options as opt
from bstool.evolve.fitness import ToyEvaluator, sequence_key
from bstool.evolve.randomize import Randomize, combine, training_robots, validation_robots
from bstool.robot.robotfile import Robot

TOY = ["--fitness", "toy", "-q"]


class Recorder:
    """The toy evaluator, remembering which robots each sequence met."""

    def __init__(self) -> None:
        self.toy = ToyEvaluator()
        self.calls: list[list[tuple[bytes, Any]]] = []

    def __call__(self, sequences: Sequence[np.ndarray], robot: Any = None) -> list[float]:
        robots = robot if isinstance(robot, list) else [robot] * len(sequences)
        self.calls.append([(sequence_key(s), r) for s, r in zip(sequences, robots, strict=True)])
        return self.toy(sequences, robot=robot)


def _plan(model: str = "ca1d", **more: Any) -> driver.Plan:
    params = opt.ga_params(
        model,
        pop=6,
        gens=more.pop("gens", 4),
        transitions=6,
        seed=5,
        **{k: more.pop(k) for k in ("robust", "coevolve_faults") if k in more},
    )
    return driver.plan_new(model, params, fitness="toy", randomize=True, **more)


def test_every_candidate_of_a_generation_meets_the_same_robots() -> None:
    plan = _plan(randomize_samples=3, validate_every=100)
    ev = Recorder()
    state = plan.state
    from bstool.evolve.engine import evolve_step

    met_by_step = []
    for step in range(3):
        before = len(ev.calls)
        seqs = state.problem.sequences("main", state.populations["main"])
        keys = [sequence_key(s) for s in seqs]
        evolve_step(state, ev)
        calls = [c for call in ev.calls[before : before + 3] for c in call]  # then validation
        robots = training_robots(Robot(), state.randomize, 5, step)  # type: ignore[arg-type]
        assert [c[1] for c in ev.calls[before]][:1] == [robots[0]]
        met = {}
        for key in set(keys):
            # the first candidate with this sequence met exactly the step's robots (CRN)
            met[key] = [r for k, r in calls if k == key]
        for key in set(keys):
            assert sorted(map(repr, met[key])) == sorted(map(repr, robots))
        met_by_step.append(robots)
    assert met_by_step[0] != met_by_step[1] != met_by_step[2]  # drawn afresh each generation


def test_the_elite_is_rescored_on_each_generations_robots() -> None:
    plan = _plan(randomize_samples=2, validate_every=100)
    ev = Recorder()
    from bstool.evolve.engine import evolve_step

    state = plan.state
    evolve_step(state, ev)
    elite = sequence_key(state.problem.sequences("main", state.populations["main"][:1])[0])
    evolve_step(state, ev)
    second = training_robots(Robot(), state.randomize, 5, 1)  # type: ignore[arg-type]
    seen = [r for call in ev.calls for k, r in call if k == elite]
    assert all(any(r == s for r in seen) for s in second)


def test_draws_are_a_function_of_the_seed_and_step() -> None:
    s = Randomize(samples=4)
    assert training_robots(Robot(), s, 1, 3) == training_robots(Robot(), s, 1, 3)
    assert training_robots(Robot(), s, 1, 3) != training_robots(Robot(), s, 2, 3)
    assert training_robots(Robot(), s, 1, 3) != training_robots(Robot(), s, 1, 4)
    valid = validation_robots(Robot(), Randomize(validation_samples=64), 1)
    assert len(valid) == 64 and not set(map(repr, valid)) & set(
        map(repr, training_robots(Robot(), Randomize(samples=64), 1, 0))
    )


def test_scores_mean_and_worst_quarter() -> None:
    d = np.array([[4.0, 1.0], [1.0, 2.0], [3.0, 3.0], [2.0, 4.0], [5.0, 5.0]])  # K=5, P=2
    assert combine(d, "mean").tolist() == [3.0, 3.0]
    assert combine(d, "worst-quarter").tolist() == [1.5, 1.5]  # the 2 lowest of 5


def test_validation_rows_and_best_json(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = [
        "evolve",
        "nnsin",
        "--pop",
        "6",
        "--gens",
        "7",
        "--seed",
        "2",
        "--randomize",
        "--randomize-samples",
        "2",
        "--validate-every",
        "3",
        "--out",
        str(out),
        *TOY,
    ]
    assert main(args) == 0
    lines = (out / "history.csv").read_text().splitlines()
    assert lines[0].endswith(",validation")
    measured = [i for i, line in enumerate(lines[1:]) if not line.endswith(",")]
    assert measured == [0, 3, 6]  # every 3 generations and the last
    best = json.loads((out / "best.json").read_text())
    want = Randomize(samples=2, validate_every=3, train_timestep=0.003).to_json()
    assert best["ga"]["randomize"] == want
    values = [float(line.rsplit(",", 1)[1]) for line in lines[1:] if not line.endswith(",")]
    assert best["fitness"] == max(values)
    # best.json's fitness is its mean over the validation robots, recomputed independently
    from bstool.controllers import load_controller

    ctrl = load_controller(out / "best.json")
    robots = validation_robots(Robot(), Randomize(validation_samples=64), 2)
    seq = ctrl.states(30)
    assert np.mean(ToyEvaluator()([seq] * 64, robot=robots)) == pytest.approx(best["fitness"])
    assert "robot" not in best  # no --robot: nothing recorded, the hash unchanged


def test_resume_after_an_interruption_is_identical(tmp_path: Path) -> None:
    common = dict(
        pop=6,
        gens=6,
        transitions=6,
        seed=9,
        fitness="toy",
        randomize=True,
        randomize_samples=3,
        validate_every=2,
    )
    driver.evolve("ca2ddiff", out=tmp_path / "whole", coevol_gens=2, **common)  # type: ignore[arg-type]

    def stop(g: driver.Generation) -> None:
        if g.step == 5:
            raise KeyboardInterrupt

    with pytest.raises(driver.EvolveInterrupted):
        driver.evolve("ca2ddiff", out=tmp_path / "cut", coevol_gens=2, on_generation=stop, **common)  # type: ignore[arg-type]
    driver.resume(tmp_path / "cut")
    for name in ("best.json", "history.csv"):
        assert (tmp_path / "cut" / name).read_text() == (tmp_path / "whole" / name).read_text()


@pytest.mark.parametrize(
    "mode", [{"robust": "mean"}, {"coevolve_faults": True}, {"randomize_score": "worst-quarter"}]
)
def test_with_the_other_scoring_modes(mode: dict[str, Any], tmp_path: Path) -> None:
    result = driver.evolve(
        "ca1d",
        pop=4,
        gens=3,
        transitions=5,
        seed=1,
        fitness="toy",
        randomize=True,
        randomize_samples=2,
        out=tmp_path / "r",
        **mode,
    )
    assert result.completed and result.fitness > 0
    rows = (tmp_path / "r" / "history.csv").read_text().splitlines()
    assert rows[0].endswith("validation") and rows[1].split(",")[-1] != ""


def test_a_robot_file_is_recorded_and_its_box_used(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text("friction = 0.6\n[uncertain]\nfriction = { scale = [0.5, 0.6] }\n")
    out = tmp_path / "run"
    assert (
        main(
            [
                "evolve",
                "ca1d",
                "--pop",
                "4",
                "--gens",
                "2",
                "--robot",
                str(path),
                "--randomize",
                "--out",
                str(out),
                *TOY,
            ]
        )
        == 0
    )
    best = json.loads((out / "best.json").read_text())
    assert best["robot"]["friction"] == 0.6
    assert best["robot"]["uncertain"] == {"friction": {"scale": [0.5, 0.6]}}
    from bstool.evolve.checkpoint import load_checkpoint

    state, _extra = load_checkpoint(out)
    assert state.robot is not None and state.robot.spec.friction == 0.6
    drawn = training_robots(state.robot, Randomize(), state.params.seed, 0)
    assert all(0.3 <= r.friction <= 0.36 for r in drawn)


def test_option_mistakes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    assert main(["evolve", "ca1d", "--randomize-samples", "3", "--out", str(out), *TOY]) == 2
    assert "only applies with --randomize" in capsys.readouterr().err
    assert (
        main(
            ["evolve", "ca1d", "--pop", "4", "--gens", "1", "--randomize", "--out", str(out), *TOY]
        )
        == 0
    )
    assert main(["evolve", "--resume", str(out), "--randomize-samples", "8", "-q"]) == 2
    err = capsys.readouterr().err
    assert "--randomize-samples is 8 but the run" in err and "with 4" in err
    assert "a resumed run keeps its settings" in err
    # an option typed with the run's own value is fine, whatever the others' defaults are now
    odd = tmp_path / "odd"
    assert main(["evolve", "ca1d", "--pop", "4", "--gens", "1", "--randomize",
                 "--train-timestep", "0.002", "--out", str(odd), *TOY]) == 0  # fmt: skip
    assert main(["evolve", "--resume", str(odd), "--randomize-samples", "4", "--gens", "2",
                 "-q"]) == 0  # fmt: skip
    assert main(["evolve", "--resume", str(odd), "--train-timestep", "0.003", "-q"]) == 2
    assert "--train-timestep is 0.003" in capsys.readouterr().err
    plain = tmp_path / "plain"
    assert main(["evolve", "ca1d", "--pop", "4", "--gens", "1", "--out", str(plain), *TOY]) == 0
    assert main(["evolve", "--resume", str(plain), "--randomize", "-q"]) == 2
    assert "started without --randomize" in capsys.readouterr().err


def test_a_cluster_gives_the_same_run(tmp_path: Path) -> None:
    distributed = pytest.importorskip("dask.distributed")
    args = dict(
        pop=4, gens=3, transitions=5, seed=4, fitness="toy", randomize=True, randomize_samples=2
    )
    driver.evolve("nnsig", out=tmp_path / "local", **args)  # type: ignore[arg-type]
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
        ) as c,
        distributed.Client(c) as client,
    ):
        driver.evolve("nnsig", out=tmp_path / "dask", cluster=client, **args)  # type: ignore[arg-type]
    for name in ("best.json", "history.csv"):
        assert (tmp_path / "local" / name).read_text() == (tmp_path / "dask" / name).read_text()


@pytest.mark.slow
def test_physics_and_stamp_timed_on_random_robots(tmp_path: Path) -> None:
    """A tiny physics run, plain and stamp-timed (schedule model of 1 build; each candidate
    on 2 builds), on 2 workers: a validated fitness that replays on the validation robots, and
    the nominal model untouched."""
    from hil_mock.schedule_model import schedule_model

    for timed, builds in ((False, None), (True, 1), (True, 2)):
        sched = schedule_model("nnsin", builds=builds) if timed else None
        result = driver.evolve(
            "nnsin",
            pop=3,
            gens=2,
            transitions=4,
            seed=3,
            randomize=True,
            randomize_samples=2,
            validation_samples=3,
            out=tmp_path / f"t{timed}{builds}",
            workers=2,
            stamp_timed=timed,
            schedule_model=sched,
            schedule_builds=builds,
        )
        assert result.completed and result.fitness > 0
        ctrl = result.controller
        assert ctrl is not None
        from bstool.evolve.fitness import PhysicsFitness, StampTimedFitness

        robots = validation_robots(Robot(), Randomize(validation_samples=3), 3)
        factory: Any = StampTimedFitness(sched) if timed else PhysicsFitness()
        ev = factory.build()
        again = np.mean(ev([ctrl.states(4)] * 3, robot=robots))
        nominal_after = ev([ctrl.states(4)])[0]
        ev.close()
        assert again == pytest.approx(result.fitness, abs=1e-12)
        fresh = factory.build()
        assert nominal_after == fresh([ctrl.states(4)])[0]  # the robots left no trace
        fresh.close()


@pytest.mark.slow
def test_training_on_a_coarser_step_validates_on_the_robots_own(tmp_path: Path) -> None:
    """--train-timestep: the training draws run at that step, the validation (best.json's
    fitness) at the robot's; recorded in the run."""
    from bstool.evolve.fitness import PhysicsFitness

    result = driver.evolve(
        "nnsig", pop=3, gens=2, transitions=4, seed=8, randomize=True, randomize_samples=2,
        validation_samples=2, train_timestep=0.004, out=tmp_path / "r", workers=2,
    )  # fmt: skip
    settings = Randomize(samples=2, validation_samples=2, train_timestep=0.004)
    assert [r.timestep for r in training_robots(Robot(), settings, 8, 0)] == [0.004, 0.004]
    best = json.loads((tmp_path / "r" / "best.json").read_text())
    assert best["ga"]["randomize"]["train_timestep"] == 0.004
    ctrl = result.controller
    assert ctrl is not None
    ev = PhysicsFitness().build()
    robots = validation_robots(Robot(), settings, 8)
    assert all(r.timestep == 0.002 for r in robots)
    again = float(np.mean(ev([ctrl.states(4)] * 2, robot=robots)))
    ev.close()
    assert again == pytest.approx(result.fitness, abs=1e-12)


@pytest.mark.parametrize("model", ["nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff"])
def test_init_starts_from_a_controller(model: str, tmp_path: Path) -> None:
    """--init C.json: the chromosomes decode back to C (every model), row 0 of generation 0
    is C itself, and the run records where it started."""
    from conftest import traced_controller

    from bstool.controllers import load_controller
    from bstool.evolve.problem import Problem

    ctrl = load_controller(traced_controller(model))
    problem = Problem(model)
    bits = problem.chromosomes(ctrl)
    if model == "ca2ddiff":
        again = problem.controller("leg", bits["leg"], bits["control"])
    else:
        again = problem.controller("main", bits["main"])
    assert np.array_equal(again.states(30), ctrl.states(30))
    plan = driver.plan_new(model, opt.ga_params(model, pop=4, gens=1, seed=1), fitness="toy",
                           init=traced_controller(model))  # fmt: skip
    for name in problem.populations:
        assert np.array_equal(plan.state.populations[name][0], bits[name])
    assert plan.extra["init"]["controller_hash"] == ctrl.hash()
    toy = ToyEvaluator()([ctrl.states(30)])[0]
    result = driver.execute(plan)
    assert result.history[0].best >= toy - 1e-12


@pytest.mark.slow
def test_simulate_stamp_timed_replays_a_randomized_fitness(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`simulate --stamp-timed` gives a randomized run's fitness back to the bit: the mean over
    its validation robots (its seed, its settings), with the nominal distance beside it."""
    out = tmp_path / "run"
    assert main(["evolve", "nnsig", "--pop", "3", "--gens", "1", "--seed", "5", "--stamp-timed",
                 "--randomize", "--randomize-samples", "2", "--validation-samples", "4",
                 "--out", str(out), "-q"]) == 0  # fmt: skip
    capsys.readouterr()
    best = json.loads((out / "best.json").read_text())
    assert main(["simulate", str(out / "best.json"), "--stamp-timed", "--json", "-q"]) == 0
    replay = json.loads(capsys.readouterr().out)
    assert replay["fitness"] == best["fitness"]
    assert replay["nominal_fitness"] == replay["distance"] != best["fitness"]
    assert "4 validation robots" in replay["note"]


def test_settings_and_robots_that_cannot_be_randomized(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An unknown key in a run's saved settings (a newer bstool's, or a hand edit) is an error
    that names it; an empty [uncertain] table would draw K copies of the nominal robot: refused;
    a randomized run's file without its seed cannot draw its validation robots: refused."""
    from bstool.errors import InputError

    with pytest.raises(InputError, match="unknown keys bogus"):
        Randomize.from_json({**Randomize().to_json(), "bogus": 1})
    empty = tmp_path / "empty.toml"
    empty.write_text('format = "bstool.robot/1"\n[uncertain]\n')
    out = tmp_path / "run"
    args = ["evolve", "ca1d", "--pop", "4", "--gens", "1", "--randomize", "--out", str(out)]
    assert main([*args, "--robot", str(empty), *TOY]) == 2
    assert "empty [uncertain] table" in capsys.readouterr().err and not out.exists()


@pytest.mark.slow
def test_a_randomized_file_without_its_seed_is_not_replayed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert main(["evolve", "nnsig", "--pop", "2", "--gens", "1", "--seed", "5", "--stamp-timed",
                 "--randomize", "--randomize-samples", "1", "--validation-samples", "1",
                 "--transitions", "2", "--out", str(out), "-q"]) == 0  # fmt: skip
    data = json.loads((out / "best.json").read_text())
    data.pop("seed")
    bad = tmp_path / "noseed.json"
    bad.write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["simulate", str(bad), "--stamp-timed", "--json", "-q"]) == 2
    assert "records no seed" in capsys.readouterr().err


def test_a_box_of_its_own_trains_on_it_and_keeps_the_robots_uncertainty(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--randomize-box: training and validation draws come from the box file's [uncertain]
    table; best.json records the robot as given (here the default one, so the default box
    for sensitivity and reports) and the box in ga.randomize."""
    corner = tmp_path / "corner.toml"
    corner.write_text(
        '[uncertain]\nfriction = { range = [0.85, 1.0], distribution = "log-uniform" }\n'
    )
    out = tmp_path / "run"
    args = ["evolve", "ca1d", "--pop", "4", "--gens", "2", "--randomize", "--randomize-samples",
            "3", "--validation-samples", "5", "--randomize-box", str(corner)]  # fmt: skip
    assert main([*args, "--out", str(out), *TOY]) == 0
    best = json.loads((out / "best.json").read_text())
    box = {"friction": {"range": [0.85, 1.0], "distribution": "log-uniform"}}
    assert best["ga"]["randomize"]["box"] == box
    assert "robot" not in best or "uncertain" not in best["robot"]  # the robot: the default
    from bstool.evolve.checkpoint import load_checkpoint

    state, extra = load_checkpoint(out)
    assert extra["randomize"]["box"] == box and state.randomize is not None
    robot = state.robot or Robot()
    for step in range(2):
        drawn = training_robots(robot, state.randomize, state.params.seed, step)
        assert all(0.85 <= r.friction <= 1.0 for r in drawn)
        assert {r.servo_torque for r in drawn} == {robot.spec.servo_torque}  # not in the box
    checks = validation_robots(robot, state.randomize, state.params.seed)
    assert len(checks) == 5 and all(0.85 <= r.friction <= 1.0 for r in checks)
    # without the box, the same seed draws from the robot's own (default) box
    plain = training_robots(robot, Randomize(samples=3), state.params.seed, 0)
    assert any(r.servo_torque != robot.spec.servo_torque for r in plain)
    # resume: the same box is fine, another is refused
    assert main(["evolve", "--resume", str(out), "--randomize-box", str(corner), "--gens", "3",
                 "-q"]) == 0  # fmt: skip
    other = tmp_path / "other.toml"
    other.write_text("[uncertain]\nfriction = { range = [0.3, 1.0] }\n")
    assert main(["evolve", "--resume", str(out), "--randomize-box", str(other), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--randomize-box: the file's [uncertain] table is not the box the run in" in err
    assert "(another box)" in err and "a resumed run keeps its settings" in err


def test_box_mistakes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    none = tmp_path / "none.toml"
    none.write_text("friction = 0.5\n")
    empty = tmp_path / "empty.toml"
    empty.write_text("[uncertain]\n")
    absolute = tmp_path / "absolute.toml"
    absolute.write_text("[uncertain]\nfriction = { range = [0.0, 1.0] }\n")
    base = ["evolve", "ca1d", "--pop", "4", "--gens", "1", "--out", str(out), *TOY]
    assert main([*base, "--randomize-box", str(none)]) == 2
    assert "--randomize-box only applies with --randomize" in capsys.readouterr().err
    assert main([*base, "--randomize", "--randomize-box", str(none)]) == 2
    assert f"{none} has no [uncertain] table" in capsys.readouterr().err
    assert main([*base, "--randomize", "--randomize-box", str(empty)]) == 2
    assert f"{empty} has an empty [uncertain] table" in capsys.readouterr().err
    assert main([*base, "--randomize", "--randomize-box", str(absolute)]) == 2
    assert "uncertain.friction" in capsys.readouterr().err  # a range reaching 0: named
    assert main([*base, "--randomize", "--randomize-box", str(tmp_path / "nope.toml")]) == 2
    assert "--randomize-box: robot file not found" in capsys.readouterr().err
    assert not out.exists()  # nothing written by a refused run


def test_a_box_is_taken_around_the_runs_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    robot = tmp_path / "robot.toml"
    robot.write_text("friction = 0.6\n[uncertain]\n")  # an empty table: the box supplies one
    box = tmp_path / "box.toml"
    box.write_text("[uncertain]\nfriction = { scale = [0.5, 0.6] }\n")
    out = tmp_path / "run"
    base = ["evolve", "ca1d", "--pop", "4", "--gens", "1", "--randomize",
            "--validation-samples", "3", "--robot", str(robot)]  # fmt: skip
    assert main([*base, "--randomize-box", str(box), "--out", str(out), *TOY]) == 0
    from bstool.evolve.checkpoint import load_checkpoint

    state, _extra = load_checkpoint(out)
    assert state.robot is not None and state.randomize is not None
    drawn = training_robots(state.robot, state.randomize, state.params.seed, 0)
    assert all(0.3 <= r.friction <= 0.36 for r in drawn)  # x0.5-0.6 of the run's 0.6
    # a box file that states other robot values than the run's is refused, naming both
    stating = tmp_path / "stating.toml"
    stating.write_text("friction = 0.9\n[uncertain]\nfriction = { scale = [0.9, 1.1] }\n")
    assert main([*base, "--randomize-box", str(stating), "--out", str(tmp_path / "s"), *TOY]) == 2
    err = capsys.readouterr().err
    assert f"{stating} sets friction = 0.9, but the run's robot has 0.6" in err
    assert "keep only the [uncertain] table" in err and not (tmp_path / "s").exists()
    same = tmp_path / "same.toml"
    same.write_text("friction = 0.6\n[uncertain]\nfriction = { scale = [0.9, 1.1] }\n")
    assert main([*base, "--randomize-box", str(same), "--out", str(tmp_path / "m"), *TOY]) == 0
    # resuming a run started without a box, with one: refused, saying so
    plain = tmp_path / "plain"
    assert main([*base[:-2], "--out", str(plain), *TOY]) == 0
    assert main(["evolve", "--resume", str(plain), "--randomize-box", str(box), "-q"]) == 2
    err = capsys.readouterr().err
    assert "is not the box the run in" in err and "without --randomize-box" in err


def test_the_api_takes_a_robot_as_the_box(tmp_path: Path) -> None:
    from bstool.errors import InputError
    from bstool.robot.robotfile import parse

    corner = parse({"uncertain": {"friction": {"range": [0.85, 1.0]}}}, "corner")
    result = driver.evolve("ca1d", pop=4, gens=1, transitions=4, seed=3, fitness="toy",
                           randomize=True, randomize_samples=2, validation_samples=2,
                           randomize_box=corner)  # fmt: skip
    assert result.randomize is not None
    assert result.randomize["box"] == {"friction": {"range": [0.85, 1.0]}}
    with pytest.raises(InputError, match="must be a robot file"):
        driver.evolve("ca1d", pop=4, gens=1, fitness="toy", randomize=True,
                      randomize_box={"friction": {"range": [0.85, 1.0]}})  # type: ignore[arg-type]  # fmt: skip


def test_randomize_settings_keep_their_own_box() -> None:
    table = {"friction": {"range": [0.85, 1.0]}}
    settings = Randomize(box=table)
    table["friction"]["range"][0] = 0.1  # the caller's table changes; the settings do not
    out = settings.to_json()
    out["box"]["friction"]["range"][1] = 2.0  # nor through what to_json gave
    assert settings.box == {"friction": {"range": [0.85, 1.0]}}
    assert hash(settings) == hash(Randomize())  # hashable, the box left out of the hash
