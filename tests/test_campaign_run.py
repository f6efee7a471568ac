"""``bstool campaign``: runs every (model, seed) seed-major, continues after Ctrl-C or a kill to
the files of an uninterrupted campaign, adopts run folders bstool evolve wrote, and refuses a
folder of another plan or a run folder with other settings. Toy fitness, tiny budgets."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from bstool.campaign import plan as cp
from bstool.campaign import record as rec
from bstool.campaign.runner import check_runs
from bstool.commands.campaign import evolve_settings
from bstool.errors import InputError
from bstool.evolve import fitness
from bstool.evolve.checkpoint import save_outputs
from bstool.evolve.driver import plan_new
from bstool.evolve.options import ga_params

ROOT = Path(__file__).resolve().parents[1]
PLAN = """# a tiny campaign
format = "bstool.campaign/1"
models = ["nnsig", "ca1d"]
seeds = [1, 2]

[evolve]
pop = 5
gens = 4
fitness = "toy"
transitions = 2

[evolve.ca1d]
gens = 3
"""
RUNS = ["nnsig-s1", "ca1d-s1", "nnsig-s2", "ca1d-s2"]


def files(folder: Path) -> dict[str, bytes]:
    """Every run's best.json and history.csv."""
    return {
        f"{run}/{name}": (folder / "runs" / run / name).read_bytes()
        for run in RUNS
        for name in ("best.json", "history.csv")
    }


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from bstool.cli import main

    d = tmp_path_factory.mktemp("campaign")
    (d / "plan.toml").write_text(PLAN)
    assert main(["campaign", str(d / "plan.toml"), "-o", str(d / "A"), "-q"]) == 0
    return d / "A"


def campaign(cli: Any, plan: Path, out: Path, *more: str) -> Any:
    return cli("campaign", str(plan), "-o", str(out), "-q", *more)


def test_a_campaign_folder(uninterrupted: Path) -> None:
    a = uninterrupted
    assert sorted(p.name for p in (a / "runs").iterdir()) == sorted(RUNS)
    assert (a / "plan.toml").read_text() == PLAN  # a copy of the plan given
    assert (a / "report" / "index.html").is_file() and (a / "report" / "report.json").is_file()
    record = rec.load(a)
    assert [s.outcome for s in record.sessions] == ["finished"]
    assert list(record.runs) == RUNS  # seed-major
    assert record.runs["ca1d-s2"].command.startswith(
        "bstool evolve ca1d --pop 5 --gens 3 --fitness toy --transitions 2 --seed 2 --out "
    )
    assert all(r.steps == r.total_steps and r.adopted_steps == 0 for r in record.runs.values())
    assert not (a / rec.LOCK_FILE).exists()


def test_ctrl_c_then_again_equals_uninterrupted(
    uninterrupted: Path, tmp_path: Path, cli: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    real = fitness.ToyEvaluator.__call__
    calls = {"n": 0}

    def interrupted(self: Any, seqs: Any) -> Any:
        calls["n"] += 1
        if calls["n"] == 7:  # the 3rd generation of the second run
            raise KeyboardInterrupt
        return real(self, seqs)

    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", interrupted)
    done = campaign(cli, plan, tmp_path / "B")
    assert done.code == 130, done.err
    assert "Traceback" not in done.err
    assert "Interrupted after 2 of 3 generations" in done.err
    assert f"bstool campaign {plan} -o {tmp_path / 'B'}" in done.err
    assert not (tmp_path / "B" / "runs" / "nnsig-s2").exists()
    partial = cli("report", str(tmp_path / "B"), "-q")  # a report of what is finished
    assert partial.code == 0, partial.err
    shown = json.loads((tmp_path / "B" / "report" / "report.json").read_text())
    assert (shown["finished"], shown["total"]) == (1, 4)
    assert shown["unfinished"] == ["ca1d-s1", "nnsig-s2", "ca1d-s2"]
    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", real)
    calls["n"] = 0
    again = campaign(cli, plan, tmp_path / "B")
    assert again.code == 0, again.err
    assert files(tmp_path / "B") == files(uninterrupted)
    record = rec.load(tmp_path / "B")
    assert [s.outcome for s in record.sessions] == ["interrupted", "finished"]
    assert record.runs["ca1d-s1"].steps == 3  # 2 before Ctrl-C, 1 after: nothing twice
    third = campaign(cli, plan, tmp_path / "B")
    assert third.code == 0 and files(tmp_path / "B") == files(uninterrupted)


@pytest.mark.slow
def test_killed_then_again_equals_uninterrupted(tmp_path: Path) -> None:
    """A real SIGKILL in the middle (longer runs, so the kill lands inside one)."""
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace("gens = 4", "gens = 60").replace("gens = 3", "gens = 50"))
    exe = [sys.executable, "-m", "bstool", "campaign", str(plan), "-q"]
    env = {**os.environ, "BSTOOL_PROGRESS": "0"}
    full = subprocess.run([*exe, "-o", str(tmp_path / "A")], capture_output=True, env=env)
    assert full.returncode == 0, full.stderr
    proc = subprocess.Popen([*exe, "-o", str(tmp_path / "B")], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)  # fmt: skip
    marker = tmp_path / "B" / "runs" / "ca1d-s1" / "checkpoint.npz"
    deadline = time.monotonic() + 120
    while not marker.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    time.sleep(0.3)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    record = rec.load(tmp_path / "B")
    assert any(r.finished is None for r in record.runs.values()), "the kill came too late"
    assert (tmp_path / "B" / rec.LOCK_FILE).exists()  # a dead process's lock is taken over
    again = subprocess.run([*exe, "-o", str(tmp_path / "B")], capture_output=True, env=env)
    assert again.returncode == 0, again.stderr
    for run in RUNS:
        for name in ("best.json", "history.csv"):
            a = (tmp_path / "A" / "runs" / run / name).read_bytes()
            assert (tmp_path / "B" / "runs" / run / name).read_bytes() == a, (run, name)


def test_adopts_run_folders_of_bstool_evolve(uninterrupted: Path, tmp_path: Path, cli: Any) -> None:
    """A folder holding the plan and runs made by `bstool evolve` (one finished, one cut
    short at a lower --gens, as an interim shell loop leaves them) is continued."""
    d = tmp_path / "C"
    (d / "runs").mkdir(parents=True)
    (d / "plan.toml").write_text(PLAN.replace("# a tiny campaign", "# written by hand"))
    toy = ["--pop", "5", "--fitness", "toy", "--transitions", "2", "-q"]
    assert cli("evolve", "nnsig", "--gens", "4", "--seed", "1", "--out",
               str(d / "runs" / "nnsig-s1"), *toy).code == 0  # fmt: skip
    assert cli("evolve", "ca1d", "--gens", "1", "--seed", "1", "--out",
               str(d / "runs" / "ca1d-s1"), *toy).code == 0  # fmt: skip
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    done = campaign(cli, plan, d)
    assert done.code == 0, done.err
    assert files(d) == files(uninterrupted)
    record = rec.load(d)
    assert record.runs["nnsig-s1"].adopted_steps == 4 and record.runs["nnsig-s1"].steps == 0
    assert record.runs["ca1d-s1"].adopted_steps == 1 and record.runs["ca1d-s1"].steps == 2


def test_refusals(uninterrupted: Path, tmp_path: Path, cli: Any) -> None:
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.replace("pop = 5", "pop = 6"))
    other = campaign(cli, plan, uninterrupted)
    assert other.code == 2
    assert "holds the campaign of another plan" in other.err
    assert "[evolve] pop 5 against 6" in other.err and "Hint:" in other.err
    stray = tmp_path / "stray"
    stray.mkdir()
    (stray / "notes.txt").write_text("mine")
    refused = campaign(cli, plan, stray)
    assert refused.code == 2 and "holds no campaign" in refused.err
    # a run folder whose checkpoint records another --pop: named, before any run starts
    d = tmp_path / "D"
    (d / "runs").mkdir(parents=True)
    (d / "plan.toml").write_text(plan.read_text())
    toy = ["--fitness", "toy", "--transitions", "2", "-q"]
    made = cli("evolve", "ca1d", "--pop", "5", "--gens", "1", "--seed", "2", *toy,
               "--out", str(d / "runs" / "ca1d-s2"))  # fmt: skip
    assert made.code == 0
    bad = campaign(cli, plan, d)
    assert bad.code == 2
    assert "run ca1d-s2" in bad.err and "--pop 5, but the plan says 6" in bad.err
    assert not (d / "runs" / "nnsig-s1").exists()
    (d / "runs" / "ca1d-s2" / "checkpoint.npz").unlink()
    junk = campaign(cli, plan, d)
    assert junk.code == 2 and "holds no run of bstool evolve" in junk.err
    unknown = tmp_path / "unknown.toml"
    unknown.write_text(PLAN.replace("pop = 5", "popsize = 5"))
    named = campaign(cli, unknown, tmp_path / "E")
    assert named.code == 2 and "unknown key 'popsize'" in named.err
    assert not (tmp_path / "E").exists()


def test_a_running_campaign_holds_the_folder(uninterrupted: Path, cli: Any) -> None:
    lock = uninterrupted / rec.LOCK_FILE
    lock.write_text(f"{os.getpid()}\n")  # a live process
    try:
        done = campaign(cli, uninterrupted / "plan.toml", uninterrupted)
        assert done.code == 2 and "another bstool campaign" in done.err
    finally:
        lock.unlink()


def test_the_paper_plan_adopts_the_interim_loops_runs(tmp_path: Path) -> None:
    """campaigns/paper's runs are written by `bstool evolve MODEL --pop 50 --gens 100 --seed S`
    (ca2ddiff: --gens 3 --coevol-gens 20): examples/paper.toml accepts them as its own."""
    settings = evolve_settings()
    plan = cp.load(ROOT / "examples" / "paper.toml", settings)
    for model in plan.models:
        extra = {"gens": 3, "coevol_gens": 20} if model == "ca2ddiff" else {"gens": 100}
        p = plan_new(model, ga_params(model, pop=50, seed=1, **extra), fitness="physics")
        save_outputs(p.state, tmp_path / "runs" / f"{model}-s1", p.extra)
    runs = check_runs(tmp_path, plan, settings)
    assert [r.steps_done for r in runs[:5]] == [0] * 5
    p = plan_new("nnsin", ga_params("nnsin", pop=40, gens=100, seed=2), fitness="physics")
    save_outputs(p.state, tmp_path / "runs" / "nnsin-s2", p.extra)
    with pytest.raises(InputError, match=r"run nnsin-s2 .* --pop 40, but the plan says 50"):
        check_runs(tmp_path, plan, settings)


def test_time_left_goes_by_each_models_pace() -> None:
    from bstool.campaign import pace

    record = rec.Record()
    record.run("ca1d-s1").wall_s, record.run("ca1d-s1").steps = 600.0, 100  # 6 s a generation
    record.run("ca2ddiff-s1").wall_s, record.run("ca2ddiff-s1").steps = 120.0, 120  # 1 s
    models = {"ca1d-s1": "ca1d", "ca2ddiff-s1": "ca2ddiff", "ca1d-s2": "ca1d",
              "ca2ddiff-s2": "ca2ddiff", "nnsin-s2": "nnsin"}  # fmt: skip
    rates = pace.per_model(models, record)
    assert rates == {"ca1d": 6.0, "ca2ddiff": 1.0}
    left = {"ca1d-s1": 0, "ca2ddiff-s1": 0, "ca1d-s2": 50, "ca2ddiff-s2": 120, "nnsin-s2": 10}
    # nnsin not timed yet: the mean of the models that are (3.5 s a generation)
    assert pace.seconds_left(left, models, rates) == 50 * 6 + 120 * 1 + 10 * 3.5
    assert pace.seconds_left({"nnsin-s2": 10}, models, {}, fallback=2.0) == 20.0
    assert pace.seconds_left({"nnsin-s2": 10}, models, {}) is None
    assert [pace.text(s) for s in (None, 25 * 60, 3 * 3600)] == ["?", "25 min", "3.0 h"]


def test_a_log_gets_the_time_left(
    tmp_path: Path, cli: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without a progress bar (stderr is not a terminal here), a line every few generations."""
    from bstool.commands import campaign as command

    monkeypatch.setattr(command, "PROGRESS_EVERY", 2)
    (tmp_path / "plan.toml").write_text(PLAN)
    run = cli("campaign", str(tmp_path / "plan.toml"), "-o", str(tmp_path / "C"))
    assert run.code == 0, run.err
    lines = [x for x in run.err.splitlines() if " left (" in x]
    assert lines[0].startswith("campaign: nnsig-s1 generation 2 of 4, best ")
    assert not [x for x in lines if "about ? left" in x]
    assert len(lines) == 4  # generation 2 of each run (its last one is the "finished" line)


def test_generations_no_session_timed_are_said_so(
    uninterrupted: Path, tmp_path: Path, cli: Any
) -> None:
    """A session killed before it saved its record leaves generations that no time covers:
    the run's wall time and the campaign's say they are lower bounds."""
    import shutil

    d = tmp_path / "K"
    shutil.copytree(uninterrupted, d)
    record = rec.load(d)
    run = record.runs[RUNS[0]]
    made = run.steps
    run.steps = made - 1  # as if the last generation's session had been killed
    rec.save(d, record)
    assert cli("report", str(d), "-q", "--force").code == 0
    tables = (d / "report" / "tables.md").read_text()
    assert f"for {made - 1} of its {made} generations |" in tables
    assert "1 generation was made by a session killed before it saved its time" in tables
    html = (d / "report" / "index.html").read_text()
    assert "so it is a lower bound" in html
    shown = json.loads((d / "report" / "report.json").read_text())
    assert sum(r["untimed_steps"] for r in shown["runs"]) == 1


def test_a_randomize_box_in_the_plan_is_recorded_and_held_to(
    tmp_path: Path, cli: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`randomize-box` (a path, relative to where the campaign runs) reaches each run, which
    records the table; a box file changed afterwards no longer matches the runs."""
    monkeypatch.chdir(tmp_path)
    box = tmp_path / "box.toml"
    box.write_text("[uncertain]\nfriction = { range = [0.85, 1.0] }\n")
    plan = tmp_path / "plan.toml"
    plan.write_text(
        PLAN.replace('models = ["nnsig", "ca1d"]', 'models = ["ca1d"]')
        .replace("seeds = [1, 2]", "seeds = [1]")
        .replace("[evolve.ca1d]\ngens = 3\n", "")
        + "randomize = true\nrandomize-samples = 2\nvalidation-samples = 2\n"
        + 'randomize-box = "box.toml"\n'
    )
    assert campaign(cli, plan, tmp_path / "R").code == 0
    best = json.loads((tmp_path / "R" / "runs" / "ca1d-s1" / "best.json").read_text())
    assert best["ga"]["randomize"]["box"] == {"friction": {"range": [0.85, 1.0]}}
    assert campaign(cli, plan, tmp_path / "R").code == 0  # the same box: nothing to do
    box.write_text("[uncertain]\nfriction = { range = [0.3, 1.0] }\n")
    changed = campaign(cli, plan, tmp_path / "R")
    assert changed.code == 2 and "run ca1d-s1" in changed.err and "the plan says" in changed.err
