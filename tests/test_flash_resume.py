"""``flash --all`` resumes only onto stamps that prove they run the build (issue 16, item 8),
and says to use --ports when there is no terminal to prompt on (item 11)."""

from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import pytest

import hil_mock  # noqa: F401
from bstool.cli import main
from bstool.moduleid import ModuleId
from hil_mock.progdevice import ProgrammingDevice
from hil_mock.runners import ScanRunner
from hil_mock.urlhandler import add_twin, clear_twins, get_twin

sys.path.insert(0, str(Path(__file__).parent))
from test_flash_cli import make_build, slot_image

MODS = [ModuleId(0, j) for j in range(3)]


@pytest.fixture(autouse=True)
def _fast(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BSTOOL_FLASH_FAST", "1")
    clear_twins()


def fresh_stamps() -> dict[str, ProgrammingDevice]:
    """New twins on the same ports: empty EEPROMs, nothing to announce."""
    clear_twins()
    return {m.label: add_twin(m.label, ProgrammingDevice(runner=ScanRunner())) for m in MODS}


def setup(tmp_path: Path) -> tuple[Path, Path]:
    build = make_build(tmp_path / "build", MODS)
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({m.label: f"bstwin://{m.label}" for m in MODS}))
    fresh_stamps()
    assert main(["flash", "--all", "--ports", str(ports), str(build), "-q"]) == 0
    return build, ports


def test_fresh_stamps_are_flashed_although_the_progress_file_says_done(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build, ports = setup(tmp_path)
    capsys.readouterr()
    devs = fresh_stamps()
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 0
    out, err = capsys.readouterr()
    assert "flashed earlier" not in out and "3 flashed, 0 failed" in out
    assert (
        "L0.M0: flash-progress.json says flashed, but the stamp does not announce "
        "L0.M0 3fa9c0d1 (nothing heard): flashing it again" in err
    )
    assert all(devs[m.label].eeprom.slot(0) == slot_image(m.label, 0) for m in MODS)


def test_stamps_that_announce_the_build_are_skipped_and_force_reflashes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build, ports = setup(tmp_path)
    capsys.readouterr()
    devs = {m.label: get_twin(m.label) for m in MODS}
    sessions = {k: d.sessions for k, d in devs.items()}
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 0
    out = capsys.readouterr().out
    assert out.count("flashed earlier  (checked") == 3
    assert {k: d.sessions for k, d in devs.items()} == sessions
    assert main(["flash", "--all", "--ports", str(ports), str(build), "--force"]) == 0
    assert "flashed earlier" not in capsys.readouterr().out
    assert all(d.sessions == sessions[k] + 1 for k, d in devs.items())


def test_a_swapped_cable_is_not_trusted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build, ports = setup(tmp_path)
    capsys.readouterr()
    swapped = {"L0.M0": "bstwin://L0.M1", "L0.M1": "bstwin://L0.M0", "L0.M2": "bstwin://L0.M2"}
    ports.write_text(json.dumps(swapped))
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 0
    out, err = capsys.readouterr()
    assert "the stamp announces L0.M1 3fa9c0d1, not L0.M0 3fa9c0d1" in err
    assert "L0.M2    flashed earlier" in out
    assert get_twin("L0.M1").eeprom.slot(0) == slot_image("L0.M0", 0)


def test_no_listen_cannot_check_so_it_flashes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build, ports = setup(tmp_path)
    capsys.readouterr()
    assert main(["flash", "--all", "--ports", str(ports), str(build), "--no-listen"]) == 0
    out, err = capsys.readouterr()
    assert "flashed earlier" not in out and "cannot be checked" in err


def test_all_without_a_terminal_says_to_use_ports(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    build = make_build(tmp_path / "build", MODS)
    fresh_stamps()
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))  # no input at all, as under cron
    assert main(["flash", "--all", "-p", "bstwin://L0.M0", str(build)]) == 2
    err = capsys.readouterr().err
    assert "Aborted" not in err and "standard input ended" in err and "--ports FILE" in err


def test_progress_file_that_cannot_be_written_is_refused_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build = make_build(tmp_path / "build", MODS)
    (build / "flash-progress.json").mkdir()
    devs = fresh_stamps()
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({m.label: f"bstwin://{m.label}" for m in MODS}))
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 2
    assert "cannot write flash progress file" in capsys.readouterr().err
    assert all(d.sessions == 0 for d in devs.values())
