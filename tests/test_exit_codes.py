"""Every cell of docs/cli.md's exit-code table, run through the installed ``bstool`` console
script as a subprocess: the path a shell script or CI job takes (``bstool.cli.main`` and its
``sys.exit``), which click's CliRunner and in-process calls skip. The table and the cases here
must name the same cells."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import traced_controller

from bstool.cli import COMMANDS

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "docs" / "cli.md"
CTRL = traced_controller("ca1d")
BUILD_CTRL = traced_controller("ca2dsing")


def console_script() -> str:
    """The ``bstool`` that ``pip install`` put beside this interpreter."""
    here = Path(sys.executable).with_name("bstool")
    found = str(here) if here.exists() else shutil.which("bstool")
    assert found, "the bstool console script is not installed (pip install -e .)"
    return found


def run(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [console_script(), *args],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, **(env or {})},
        stdin=subprocess.DEVNULL,
    )


def table_cells() -> set[tuple[str, int]]:
    """(command, code) of every cell of the per-command table that is not "—"."""
    cells = set()
    rows = [line for line in TABLE.read_text().splitlines() if line.startswith("| ")]
    header = next(r for r in rows if r.startswith("| command |"))
    codes = [int(c) for c in header.strip("|").split("|")[1:]]
    for row in rows[rows.index(header) + 1 :]:
        parts = [p.strip() for p in row.strip("|").split("|")]
        name = parts[0].strip("`")
        for code, cell in zip(codes, parts[1:], strict=True):
            if cell != "—":
                cells.add((name, code))
    return cells


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("exit-codes")
    bad = d / "bad.json"
    bad.write_text('{"format": "bstool.controller/1",\n "model": }')
    plain = d / "afile"
    plain.write_text("not a folder")
    source = d / "bad.bsx"
    source.write_text("' {$STAMP BS2sx}\n' {$PBASIC 2.5}\nGOTO nowhere\n")
    good_source = d / "good.bsx"
    good_source.write_text("' {$STAMP BS2sx}\n' {$PBASIC 2.5}\nHIGH 0\nEND\n")
    badrobot = d / "robot.toml"
    badrobot.write_text("frction = 0.5\n")
    calibration = d / "servos.json"
    calibration.write_text(json.dumps({"format": "bstool.servos/1", "legs": 4}))
    build = d / "build"
    assert run("compile", str(BUILD_CTRL), "-o", str(build), "-q").returncode == 0
    damaged = d / "damaged"
    shutil.copytree(build, damaged)
    image = next(damaged.rglob("*.eeprom"))
    data = bytearray(image.read_bytes())
    data[-1] ^= 0xFF
    image.write_bytes(bytes(data))
    run_dir = d / "run"
    assert (
        run(
            "evolve",
            "ca1d",
            "--fitness",
            "toy",
            "--pop",
            "4",
            "--gens",
            "1",
            "--seed",
            "1",
            "--out",
            str(run_dir),
            "-q",
        ).returncode
        == 0
    )
    (d / "plans").mkdir()
    plan = d / "plans" / "plan.toml"
    plan.write_text(
        'format = "bstool.campaign/1"\nmodels = ["nnsig"]\nseeds = [1]\n'
        '[evolve]\npop = 4\ngens = 1\nfitness = "toy"\ntransitions = 2\n'
    )
    bad_plan = d / "plans" / "bad-plan.toml"
    bad_plan.write_text(plan.read_text().replace("pop = 4", "popp = 4"))
    return {
        "dir": d,
        "plan": plan,
        "bad_plan": bad_plan,
        "bad": bad,
        "file": plain,
        "source": source,
        "good_source": good_source,
        "calibration": calibration,
        "badrobot": badrobot,
        "build": build,
        "damaged": damaged,
        "run": run_dir,
    }


#: the arguments of each cell; {name} is a file of the ``files`` fixture, {ctrl} a controller
CASES: dict[tuple[str, int], str] = {
    ("every command", 0): "--help",
    ("every command", 2): "--no-such-option",
    ("demo", 0): "demo -T 2 -q",
    ("demo", 1): "<patched demo>",
    ("demo", 2): "demo --controller {bad} -q",
    ("simulate", 0): "simulate {ctrl} -T 2",
    ("simulate", 2): "simulate {bad}",
    ("model", 0): "model --xml {dir}/robot.xml",
    ("model", 2): "model --xml {file}/robot.xml",
    ("states", 0): "states {ctrl} -T 2",
    ("states", 2): "states {bad}",
    ("evolve", 0): "evolve nnsin --fitness toy --pop 4 --gens 1 --out {dir}/evolved -q",
    ("evolve", 2): "evolve ca9d",
    ("plot-history", 0): "plot-history {run} -o {dir}/history.png",
    ("plot-history", 2): "plot-history {dir}",
    ("tokenize", 0): "tokenize {good_source} -o {dir}/slots",
    ("tokenize", 2): "tokenize {dir}/missing.bsx",
    ("tokenize", 3): "tokenize {source} -o {dir}/s3",
    ("compile", 0): "compile {ctrl} -o {dir}/c0 -q",
    ("compile", 2): "compile {bad} -o {dir}/c2",
    ("compile", 5): "compile {ctrl} -o {dir}/c5 --calibration {calibration}",
    ("flash", 0): "flash --port bstwin://exit0 {build} --module 2.3",
    ("flash", 2): "flash --port bstwin://exit2 {dir}/nobuild",
    ("flash", 4): "flash --port {dir}/ttyNONE {build} --module 2.3",
    ("flash", 5): "flash --port bstwin://exit5 {damaged} --all",
    ("probe", 0): "<served probe>",
    ("probe", 2): "probe --port bstwin://p2 -o {file}/t.json",
    ("probe", 4): "probe --port {dir}/ttyNONE -o {dir}/t.json",
    ("twin", 0): "twin {build} --no-physics -T 3 -q",
    ("twin", 1): "twin {build} --no-physics -T 3 -q --controller {ctrl}",
    ("twin", 2): "twin {build} --cut 0.0",
    ("twin", 5): "twin {damaged} --no-physics -T 3 -q",
    ("faults", 0): "faults {ctrl} -T 1 --k 1 --samples 1 -q",
    ("faults", 2): "faults {bad}",
    ("extrapolate", 0): "extrapolate {ctrl} -T 2 --no-reinit -q",
    ("extrapolate", 2): "extrapolate {bad}",
    ("paths", 0): "paths {ctrl} -T 2 -q",
    ("paths", 2): "paths {bad}",
    ("rotate", 0): "rotate {ctrl} --legs 1 -T 1 -o {dir}/rotated.json",
    ("rotate", 2): "rotate {bad} --legs 1 -o {dir}/r2.json",
    ("robot", 0): "robot",
    ("robot", 2): "robot {badrobot}",
    ("sensitivity", 0): "sensitivity {ctrl} -T 1 --points 2 --samples 1 -q",
    ("sensitivity", 2): "sensitivity {ctrl} --robot {badrobot}",
    ("report", 0): "report {run} -T 2 --extrapolate 3 -o {dir}/report -q",
    ("report", 2): "report {dir} -o {dir}/r2",
    ("campaign", 0): "campaign {plan} -o {dir}/campaign -q",
    ("campaign", 2): "campaign {bad_plan} -o {dir}/campaign2",
}


def test_the_table_and_the_cases_name_the_same_cells() -> None:
    assert table_cells() == set(CASES)
    rows = {name for name, _ in table_cells()} - {"every command"}
    assert rows == set(COMMANDS), "every command has a row in docs/cli.md"


@pytest.mark.parametrize("cell", sorted(CASES), ids=lambda c: f"{c[0]}-{c[1]}")
def test_exit_code(cell: tuple[str, int], files: dict[str, Path]) -> None:
    name, code = cell
    text = CASES[cell]
    args = shlex.split(text.format(**{k: str(v) for k, v in files.items()}, ctrl=CTRL))
    if text == "<patched demo>":
        done = _patched_demo()
    elif text == "<served probe>":
        done = _served_probe(files["dir"])
    elif name == "every command":
        for command in COMMANDS:
            one = run(command, *args)
            assert one.returncode == code, (command, one.stderr)
            assert "Traceback" not in one.stderr
        return
    else:
        done = run(*args)
    assert done.returncode == code, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    if code == 1:
        assert re.search(r"DIFFERENT|STALLED|differ", done.stdout), done.stdout


def test_every_module_stalled_is_a_failure(files: dict[str, Path]) -> None:
    """`--timeout 1`: the twin says it stalled and where, no nan, and exits 1."""
    done = run("twin", str(files["build"]), "--no-physics", "-T", "10", "--timeout", "1", "-q")
    assert done.returncode == 1
    assert "STALLED: 30 of 30 modules" in done.stdout
    assert "nan" not in done.stdout and "every module's 11 states" not in done.stdout
    assert "period:     not measured" in done.stdout
    js = run("twin", str(files["build"]), "--no-physics", "-T", "10", "--timeout", "1", "--json")
    assert js.returncode == 1
    out = json.loads(js.stdout)  # strict JSON: no NaN
    assert out["verdict"] == "stalled" and out["period_mean"] is None and out["compared"] <= 3


def test_a_mismatch_says_how_many_modules_from_which_transition(files: dict[str, Path]) -> None:
    done = run(
        "twin",
        str(files["build"]),
        "--no-physics",
        "-T",
        "3",
        "-q",
        "--json",
        "--controller",
        str(CTRL),
    )
    assert done.returncode == 1
    out = json.loads(done.stdout)
    assert out["verdict"] == "different" and out["states_equal"] is False
    ref = json.loads(run("states", str(CTRL), "-T", "3").stdout)
    twin = out["states"]
    differ = {
        (i, j)
        for i in range(5)
        for j in range(6)
        if [f[i][j] for f in twin] != [f[i][j] for f in ref]
    }
    earliest = min(t for t in range(4) if twin[t] != ref[t])
    assert len(out["mismatched"]) == len(differ)
    assert out["first_mismatch"]["transition"] == earliest
    text = run(
        "twin", str(files["build"]), "--no-physics", "-T", "3", "-q", "--controller", str(CTRL)
    ).stdout
    assert f"{len(differ)} of 30 modules, from transition {earliest}" in text


@pytest.mark.parametrize("command", ["evolve", "twin"])
def test_ctrl_c_is_130(command: str, files: dict[str, Path]) -> None:
    args = {
        "evolve": [
            "evolve",
            "ca1d",
            "--pop",
            "6",
            "--gens",
            "50",
            "--workers",
            "1",
            "--out",
            str(files["dir"] / "interrupted"),
            "-q",
        ],
        "twin": ["twin", str(files["build"]), "-T", "200", "-q"],
    }[command]
    # a shell that starts a job in the background ignores SIGINT in it, and a Python child
    # would then never raise KeyboardInterrupt: a handled signal is reset to the default at
    # exec, so the child starts with SIGINT as under a terminal
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(
            [console_script(), *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            stdin=subprocess.DEVNULL,
        )
    finally:
        signal.signal(signal.SIGINT, old)
    marker = files["dir"] / "interrupted" / "checkpoint.npz"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # evolve: interrupt once a generation is saved
        if command == "twin" or marker.exists():
            break
        time.sleep(0.2)
    time.sleep(3.0 if command == "twin" else 0.5)
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    if command == "evolve":
        assert "--resume" in err


def _patched_demo() -> subprocess.CompletedProcess[str]:
    """demo's verdict path: the same ``bstool.cli.main`` the console script calls, with the
    twin's check made to report one module different (no real build differs)."""
    code = """
import sys
import hil_mock.session as session
from bstool.moduleid import ModuleId
real = session.run_twin
def run_twin(build, options):
    report = real(build, options)
    report.check.mismatched = [ModuleId(0, 1)]
    report.check.states_equal = False
    report.check.first_mismatch = {"module": "0.1", "transition": 1, "twin": [1],
                                   "reference": [2]}
    return report
session.run_twin = run_twin
from bstool.cli import main
sys.exit(main(["demo", "-T", "2", "-q"]))
"""
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=600,
        stdin=subprocess.DEVNULL,
    )


def _served_probe(folder: Path) -> subprocess.CompletedProcess[str]:
    serve = subprocess.Popen(
        [sys.executable, "-m", "hil_mock", "serve", "--timing", "real"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert serve.stdout is not None
        _label, port = serve.stdout.readline().split()
        return run("probe", "--port", port, "--quick", "-q", "-o", str(folder / "timing.json"))
    finally:
        serve.terminate()
        serve.wait(timeout=5)
