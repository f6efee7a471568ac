"""Outputs of the experiment, simulate, model, tokenize and plot commands (issues 15/16):
every output path checked before the work (exit 2, one line, nothing simulated), folders
replaced whole with the user's umask, never replacing a foreign folder or the inputs, slot
sets that are never mixed, and temporaries of killed runs cleaned by the next run."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import traced_controller

from bstool.cli import main

TOKENIZER_VECTORS = Path(__file__).parent / "vectors" / "tokenizer"
PROJECT = TOKENIZER_VECTORS / "multi_robot_rules"
# twin --video is checked before the build is even read
BUILD = Path(__file__).parent / "golden" / "compile" / "ca1d"  # not a build: twin must not care
HISTORY = "generation,best,mean,population,evaluations\n0,0.02,0.01,main,10\n"


@pytest.fixture
def ctrl(tmp_path: Path) -> Path:
    path = tmp_path / "nnsin.json"
    shutil.copy(traced_controller("nnsin"), path)
    return path


@pytest.fixture
def no_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Building a simulator at all means the output was checked too late."""
    from bstool.sim import batch, simulator
    from bstool.tokenizer import project

    def boom(*_a: object, **_k: object) -> None:
        raise AssertionError("work started before the output path was checked")

    monkeypatch.setattr(simulator.Simulator, "__init__", boom)
    monkeypatch.setattr(batch.BatchEvaluator, "__init__", boom)
    monkeypatch.setattr(project, "tokenize_file", boom)
    monkeypatch.setattr("bstool.commands.tokenize.tokenize_file", boom, raising=False)


def _cases(ctrl: Path, run: Path, bad: Path) -> dict[str, list[str]]:
    return {
        "rotate -o": ["rotate", str(ctrl), "--legs", "1", "-o", str(bad / "r.json")],
        "model --xml": ["model", "--xml", str(bad / "robot.xml")],
        "faults --plot": ["faults", str(ctrl), "--plot", str(bad / "f.png")],
        "faults --k --plot": ["faults", str(ctrl), "--k", "2", "--plot", str(bad / "f.png")],
        "simulate --plot": ["simulate", str(ctrl), "--plot", str(bad / "p.png")],
        "simulate --video": ["simulate", str(ctrl), "--video", str(bad / "v.mp4")],
        "paths --plot": ["paths", str(ctrl), "--plot", str(bad / "p.png")],
        "extrapolate --plot": ["extrapolate", str(ctrl), "--plot", str(bad / "e.png")],
        "plot-history -o": ["plot-history", str(run), "-o", str(bad / "h.png")],
        "report -o": ["report", str(ctrl), "-o", str(bad / "report")],
        "tokenize -o": ["tokenize", str(PROJECT / "multi_robot_rules.bsx"), "-o", str(bad / "t")],
        "compile -o": ["compile", str(ctrl), "-o", str(bad / "build")],
        "evolve --out": ["evolve", "ca1d", "--pop", "4", "--gens", "2", "--out", str(bad / "e")],
        "demo --out": ["demo", "--out", str(bad / "d")],
        "twin --video": ["twin", str(BUILD), "-T", "1", "--video", str(bad / "t.mp4")],
        "probe -o": ["probe", "--port", "/dev/nonexistent-port", "-o", str(bad / "timing.json")],
    }


CASES = list(_cases(Path("c"), Path("r"), Path("b")))


@pytest.mark.parametrize("case", CASES)
@pytest.mark.usefixtures("no_simulation")
def test_unwritable_output_fails_fast_with_one_line(
    case: str, ctrl: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "history.csv").write_text(HISTORY)
    blocker = tmp_path / "plain-file"
    blocker.write_text("not a folder")
    assert main(_cases(ctrl, run, blocker)[case]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "is a file, not a folder" in err
    assert len(err.strip().splitlines()) <= 2  # the error and its hint
    assert blocker.read_text() == "not a folder"


# -- report ----------------------------------------------------------------------------------
REPORT = ["-T", "1", "--extrapolate", "2", "-q", "--workers", "1"]


def _run_dir(tmp_path: Path) -> Path:
    run = tmp_path / "runs" / "nnsin"
    run.mkdir(parents=True)
    shutil.copy(traced_controller("nnsin"), run / "best.json")
    (run / "history.csv").write_text(HISTORY)
    (run / "checkpoint.npz").write_bytes(b"precious")
    return run


@pytest.mark.usefixtures("no_simulation")
def test_report_never_replaces_its_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _run_dir(tmp_path)
    before = {p.name: p.read_bytes() for p in run.iterdir()}
    for out in (run, run.parent):
        for force in ([], ["--force"]):
            assert main(["report", str(run), "-o", str(out), *REPORT, *force]) == 2
            assert "would replace the input" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in run.iterdir()} == before


@pytest.mark.usefixtures("no_simulation")
def test_report_refuses_a_foreign_folder(
    ctrl: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep")
    assert main(["report", str(ctrl), "-o", str(out), *REPORT]) == 2
    err = capsys.readouterr().err
    assert "not empty and was not made by this command" in err and "--force" in err
    # a folder that looks like a report but holds a file of the user's is not ours either
    (out / "index.html").write_text('<meta name="generator" content="bstool report 1">')
    assert main(["report", str(ctrl), "-o", str(out), *REPORT]) == 2
    assert (out / "notes.txt").read_text() == "keep"


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_report_force_umask_rerun_and_stale_temporaries(
    ctrl: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("x")
    dead = _dead_pid()
    for kind in ("new", "old"):  # what a killed report left beside its folder
        (tmp_path / f".out.{kind}-{dead}-abc").mkdir()
    old = os.umask(0o022)
    try:
        assert main(["report", str(ctrl), "-o", str(out), *REPORT, "--force"]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    assert not (out / "old.txt").exists() and (out / "index.html").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nnsin.json", "out"]
    # an earlier report is ours: replaced without --force
    assert main(["report", str(ctrl), "-o", str(out), *REPORT]) == 0
    assert "report:" in capsys.readouterr().out


# -- tokenize --------------------------------------------------------------------------------
def _project(tmp_path: Path) -> Path:
    src = tmp_path / "src"
    shutil.copytree(PROJECT, src)
    for p in src.iterdir():
        if p.suffix != ".bsx":
            p.unlink()
    return src / "multi_robot_rules.bsx"


def _slots(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _shrink(main_file: Path) -> None:
    """The same project, one slot fewer: slot 2 is no longer listed."""
    text = main_file.read_text()
    main_file.write_text(text.replace(", lr_rules.bsx}", "}", 1))


def test_tokenize_folder_rules(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    main_file = _project(tmp_path)
    out = tmp_path / "slots"
    assert main(["tokenize", str(main_file), "-o", str(out)]) == 0
    assert (out / "slot2.eeprom").read_bytes() == (PROJECT / "slot2.eeprom").read_bytes()
    assert (out / "tokenize.json").exists()
    _shrink(main_file)
    assert main(["tokenize", str(main_file), "-o", str(out)]) == 0  # ours: replaced whole
    assert sorted(_slots(out)) == ["slot0.eeprom", "slot0.packets", "slot1.eeprom",
                                   "slot1.packets", "tokenize.json"]  # fmt: skip
    capsys.readouterr()
    # another project's slot folder, a foreign folder, the sources' folder: refused
    other = tmp_path / "other.bsx"
    shutil.copy(TOKENIZER_VECTORS / "io_pin_commands" / "io_pin_commands.bsx", other)
    assert main(["tokenize", str(other), "-o", str(out)]) == 2
    assert "not made by this command" in capsys.readouterr().err
    assert main(["tokenize", str(other), "-o", str(out), "--force"]) == 0
    for force in ([], ["--force"]):
        assert main(["tokenize", str(main_file), "-o", str(main_file.parent), *force]) == 2
        assert "would replace the input" in capsys.readouterr().err
    assert main_file.exists()


def test_tokenize_default_folder_and_umask(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    main_file = _project(tmp_path)
    monkeypatch.chdir(tmp_path)
    old = os.umask(0o022)
    try:
        assert main(["tokenize", str(main_file)]) == 0
    finally:
        os.umask(old)
    out = tmp_path / "multi_robot_rules.slots"
    assert stat.S_IMODE(out.stat().st_mode) == 0o755 and (out / "slot1.packets").exists()


KILLER = """
import os, sys
from bstool import fileio
from bstool.cli import main
real, count = fileio.write_bytes, [0]
def write_bytes(path, data):
    real(path, data)
    count[0] += 1
    if count[0] == int(os.environ["KILL_AFTER"]):
        os._exit(9)  # killed in the middle of writing the slot set
fileio.write_bytes = write_bytes
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("kill_after", [1, 2, 3])
def test_a_killed_tokenize_leaves_the_old_set_and_the_next_run_cleans_up(
    kill_after: int, tmp_path: Path
) -> None:
    main_file = _project(tmp_path)
    out = tmp_path / "slots"
    assert main(["tokenize", str(main_file), "-o", str(out)]) == 0
    old = _slots(out)
    _shrink(main_file)
    env = {
        **os.environ,
        "KILL_AFTER": str(kill_after),
        "PYTHONPATH": str(Path(__file__).parents[1]),
    }
    done = subprocess.run(
        [sys.executable, "-c", KILLER, "tokenize", str(main_file), "-o", str(out)],
        env=env,
        check=False,
    )
    assert done.returncode == 9
    assert _slots(out) == old  # never a mix of old and new slots
    assert any(p.name.startswith(".slots.new-") for p in tmp_path.iterdir())
    assert main(["tokenize", str(main_file), "-o", str(out)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["slots", "src"]  # cleaned
    assert "slot2.eeprom" not in _slots(out)


# -- the video's scratch folder -------------------------------------------------------------
def test_video_scratch_of_a_killed_run_is_removed(tmp_path: Path) -> None:
    from bstool.sim import video

    dead, live = _dead_pid(), os.getpid()
    for name in (f"bstool-video-{dead}-abc", f"bstool-video-{live}-def", "bstool-video-x1"):
        (tmp_path / name).mkdir()
    removed = video.clean_stale_scratch(tmp_path)
    assert [p.name for p in removed] == [f"bstool-video-{dead}-abc"]
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(["bstool-video-x1", f"bstool-video-{live}-def"])
