"""paths labels (item 7), progress bars and -q (item 9), --reinit-every 0 (item 10)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from conftest import traced_controller

from bstool.cli import main
from bstool.experiments.common import unique_labels
from bstool.experiments.progress import ENV


def _copy(dest: Path, model: str = "nnsin") -> Path:
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(traced_controller(model), dest)
    return dest


def test_unique_labels_say_where_they_came_from() -> None:
    assert unique_labels(["runs/nnsin/best.json", "other/nnsin.json", "a/ca1d.json"]) == [
        "nnsin (runs)",
        "nnsin (other)",
        "ca1d",
    ]
    assert unique_labels(["x/a/run/best.json", "y/a/run/best.json"]) == [
        "run (x/a)",
        "run (y/a)",
    ]
    assert unique_labels(["c.json", "c.json"]) == ["c", "c #2"]


def test_paths_keeps_every_controller(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _copy(tmp_path / "runs" / "nnsin" / "best.json")
    b = _copy(tmp_path / "other" / "nnsin.json")
    assert main(["paths", str(a), str(b), "-T", "1", "--json", "-q"]) == 0
    shapes = json.loads(capsys.readouterr().out)
    assert sorted(shapes) == ["nnsin (other)", "nnsin (runs)"]


def _ctrl(tmp_path: Path) -> str:
    return str(_copy(tmp_path / "nnsin.json"))


COMMANDS = {
    "faults": lambda c, out: ["faults", c, "-T", "1", "--workers", "1"],
    "extrapolate": lambda c, out: ["extrapolate", c, "-T", "2", "--reinit-every", "1"],
    "paths": lambda c, out: ["paths", c, "-T", "1"],
    "report": lambda c, out: [
        "report",
        c,
        "-o",
        out,
        "-T",
        "1",
        "--extrapolate",
        "2",
        "--workers",
        "1",
    ],
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_progress_bar_unless_quiet(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """Bars are drawn on a terminal; ``BSTOOL_PROGRESS=1`` forces them here (stderr is a
    pipe under pytest); ``-q`` wins over both."""
    monkeypatch.setenv(ENV, "1")
    args = COMMANDS[name](_ctrl(tmp_path), str(tmp_path / "report"))
    assert main(args) == 0
    err = capfd.readouterr().err
    assert f"{name}" in err and "%|" in err  # a tqdm bar: "faults:  50%|█████     | 16/31"
    assert main([*args, "-q"]) == 0
    assert capfd.readouterr().err == ""


def test_no_bar_when_stderr_is_not_a_terminal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv(ENV, raising=False)
    assert main(["faults", _ctrl(tmp_path), "-T", "1", "--workers", "1"]) == 0
    assert "%|" not in capfd.readouterr().err


def test_reinit_every_zero_turns_the_variant_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    c = _ctrl(tmp_path)
    assert main(["extrapolate", c, "-T", "2", "--reinit-every", "0", "--json", "-q"]) == 0
    assert list(json.loads(capsys.readouterr().out)["curves"]) == ["plain"]
    assert main(["extrapolate", c, "-T", "2", "--reinit-every", "1", "--json", "-q"]) == 0
    assert list(json.loads(capsys.readouterr().out)["curves"]) == ["plain", "reinit every 1"]
    assert main(["extrapolate", c, "--reinit-every", "-1"]) == 2
