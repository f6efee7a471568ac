"""``bstool flash`` end to end against twins: build dirs, --all with resume, messages."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from conftest import FakeModule, fake_announcing_image, write_fake_build

import hil_mock  # noqa: F401
from bstool.cli import cli, main
from bstool.flash import FlashInterrupted, flash_module, load_target
from bstool.flash.session import FAST
from bstool.moduleid import ModuleId
from bstool.wire import programming as P
from hil_mock.progdevice import Faults, ProgrammingDevice
from hil_mock.runners import ScanRunner
from hil_mock.urlhandler import add_twin, clear_twins

CHASH = "3fa9c0d1" + "e" * 56


def slot_image(label: str, slot: int, chash: str = CHASH) -> bytes:
    """A fake image whose DATA carries the announcement (the ScanRunner prints it)."""
    return fake_announcing_image(label, slot, chash)


def make_build(root: Path, modules: list[ModuleId], slots: int = 1, chash: str = CHASH) -> Path:
    """A fake compile output in the layout and manifest form of bstool compile."""
    fakes = [
        FakeModule(mid, {n: slot_image(mid.label, n, chash) for n in range(slots)})
        for mid in modules
    ]
    return write_fake_build(root, fakes, chash=chash)


@pytest.fixture(autouse=True)
def _fast(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BSTOOL_FLASH_FAST", "1")
    clear_twins()


def twin(name: str, **kw: object) -> ProgrammingDevice:
    return add_twin(name, ProgrammingDevice(runner=ScanRunner(), **kw))  # type: ignore[arg-type]


def test_flash_one_module_and_announcement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build = make_build(tmp_path / "build", [ModuleId(0, 0), ModuleId(2, 3)], slots=2)
    dev = twin("m23")
    assert main(["flash", "--port", "bstwin://m23", str(build), "--module", "2.3"]) == 0
    out = capsys.readouterr().out
    assert dev.eeprom.slot(0) == slot_image("L2.M3", 0) and dev.eeprom.slot(1) == slot_image(
        "L2.M3", 1
    )
    assert "module L2.M3 runs controller 3fa9c0d1" in out
    assert "of the 9600-baud limit (960 B/s)" in out and "records" in out


def test_wrong_module_on_the_cable(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "build", [ModuleId(0, 5)])
    manifest = json.loads((build / "manifest.json").read_text())
    manifest["modules"][0]["module"] = "0.0"  # files still those of L0.M5
    manifest["flash_order"] = [{"module": "0.0", "slots": [0]}]
    (build / "manifest.json").write_text(json.dumps(manifest))
    twin("c")
    assert main(["flash", "-p", "bstwin://c", str(build)]) == 4
    err = capsys.readouterr().err
    assert "L0.M0 was flashed but the program announces module L0.M5" in err
    assert main(["flash", "-p", "bstwin://c", str(build), "--no-listen"]) == 0


def test_announcement_mismatch_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build = make_build(tmp_path / "build", [ModuleId(1, 1)])
    dev = twin("mm")
    plan = load_target(build).modules[0]
    plan.module = ModuleId(1, 2)  # the build's image announces L1.M1
    with pytest.raises(
        Exception, match=r"L1.M2 was flashed but the program announces module L1.M1"
    ):
        flash_module("bstwin://mm", plan, timing=FAST)
    assert dev.eeprom.slot(0) == slot_image("L1.M1", 0)


def test_no_announcement_is_a_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "build", [ModuleId(0, 0)])
    add_twin("quiet", ProgrammingDevice())  # no runner: nothing is printed
    assert main(["flash", "-p", "bstwin://quiet", str(build)]) == 0
    assert "no start-up announcement from L0.M0" in capsys.readouterr().err


def test_all_with_ports_file_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mods = [ModuleId(0, j) for j in range(3)]
    build = make_build(tmp_path / "build", mods)
    devs = {m.label: twin(m.label) for m in mods}
    devs["L0.M1"].faults = Faults(dead_at_rx=0)
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({m.label: f"bstwin://{m.label}" for m in mods}))
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 4
    out = capsys.readouterr()
    assert "L0.M1    failed" in out.out and "nothing echoed" in out.out
    assert "2 flashed, 1 failed, 0 skipped" in out.out
    progress = json.loads((build / "flash-progress.json").read_text())["modules"]
    assert progress["L0.M0"]["status"] == "flashed" and progress["L0.M1"]["status"] == "failed"
    # fix the module, run again: only L0.M1 is flashed now
    devs["L0.M1"] = twin("L0.M1")
    sessions = devs["L0.M0"].sessions  # its stamp announces the build: it is not flashed again
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 0
    out = capsys.readouterr()
    assert "L0.M0    flashed earlier" in out.out and "L0.M1    flashed" in out.out
    assert devs["L0.M0"].sessions == sessions
    assert all(devs[m.label].eeprom.slot(0) == slot_image(m.label, 0) for m in mods)


def test_all_with_prompts(tmp_path: Path) -> None:
    mods = [ModuleId(1, j) for j in range(3)]
    build = make_build(tmp_path / "build", mods)
    dev = twin("bench")
    runner = CliRunner()
    result = runner.invoke(
        cli, ["flash", "--all", "-p", "bstwin://bench", str(build)], input="\ns\nq\n"
    )
    assert result.exit_code == 0, result.output
    assert "connect L1.M0, Enter to flash, s to skip, q to quit" in result.output
    assert "L1.M0    flashed" in result.output and "L1.M1    skipped" in result.output
    assert "L1.M2" not in result.output.split("module   result")[1]
    assert dev.eeprom.slot(0) == slot_image("L1.M0", 0)


def test_build_with_many_modules_needs_a_choice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0), ModuleId(0, 1)])
    assert main(["flash", "-p", "bstwin://x", str(build)]) == 2
    assert "--module L.M" in capsys.readouterr().err


def test_damaged_build_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0)])
    img = build / "modules" / "L0.M0" / "slot0.eeprom"
    img.write_bytes(b"\x01" + img.read_bytes()[1:])
    assert main(["flash", "-p", "bstwin://x", str(build)]) == 5
    assert "differs from the manifest's sha256" in capsys.readouterr().err


def test_port_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0)])
    assert main(["flash", "-p", "/dev/ttyNOPE0", str(build)]) == 4
    err = capsys.readouterr().err
    assert "port /dev/ttyNOPE0 does not exist" in err and "Hint:" in err
    assert main(["flash", "-p", "nosuch://x", str(build)]) == 4
    assert "not a usable port" in capsys.readouterr().err


def test_permission_hint_names_the_group(tmp_path: Path) -> None:
    import errno

    import serial

    from bstool.flash.port import _port_error

    dev = tmp_path / "ttyFAKE"
    dev.write_text("")
    exc = serial.SerialException(errno.EACCES, "Permission denied")
    error = _port_error(str(dev), exc)
    assert "no permission" in error.message and "group" in (error.hint or "")
    busy = _port_error(str(dev), serial.SerialException(errno.EBUSY, "busy"))
    assert "busy" in busy.message


def test_trace_dumps_both_directions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0)])
    twin("tr")
    assert main(["flash", "-p", "bstwin://tr", str(build), "--trace", "--no-listen"]) == 0
    err = capsys.readouterr().err
    assert "bstwin://tr > 58\nbstwin://tr < 58\nbstwin://tr < 5A\n" in err
    assert "no start-up announcement" not in err


def test_ctrl_c_names_the_slot(tmp_path: Path) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0)], slots=2)
    twin("cc")
    plan = load_target(build).modules[0]

    def stop(p: object) -> None:
        if getattr(p, "slot", 0) == 1:
            raise KeyboardInterrupt

    with pytest.raises(FlashInterrupted, match=r"L0.M0 slot 1 on bstwin://cc may be incomplete"):
        flash_module("bstwin://cc", plan, timing=FAST, progress=stop)


def test_controller_and_bsx_targets_explain_what_is_missing(tmp_path: Path) -> None:
    ctrl = tmp_path / "best.json"
    ctrl.write_text(json.dumps({"format": "bstool.controller/1", "model": "ca1d"}))
    other = tmp_path / "x.json"
    other.write_text("{}")
    with pytest.raises(Exception, match=r"not a build directory, a .bsx file or a controller"):
        load_target(other)
    with pytest.raises(Exception, match="--all needs a build directory"):
        load_target(_bsx(tmp_path), every_module=True)


def _bsx(tmp_path: Path) -> Path:
    p = tmp_path / "main.bsx"
    p.write_text("' {$STAMP BS2sx}\nEND\n")
    return p


def test_packets_as_hex_text_and_damaged(tmp_path: Path) -> None:
    from bstool.errors import BuildError
    from bstool.flash.target import parse_packets

    recs = P.records_for_image(slot_image("L0.M0", 0))
    assert parse_packets(b"".join(recs).hex().encode(), "x") == recs
    bad = bytearray(b"".join(recs))
    bad[3] ^= 1
    with pytest.raises(BuildError, match="record 1 is damaged"):
        parse_packets(bytes(bad), "x")


def test_ctrl_c_in_all_marks_module_incomplete(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from bstool.flash.session import Programmer

    build = make_build(tmp_path / "b", [ModuleId(0, 0), ModuleId(0, 1)])
    twin("k0")
    twin("k1")
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({"L0.M0": "bstwin://k0", "L0.M1": "bstwin://k1"}))
    real = Programmer.send_record
    calls = []

    def interrupted(self: Programmer, record: bytes) -> None:
        calls.append(record)
        if len(calls) == 5:
            raise KeyboardInterrupt
        real(self, record)

    monkeypatch.setattr(Programmer, "send_record", interrupted)
    assert main(["flash", "--all", "--ports", str(ports), str(build)]) == 130
    assert "interrupted: L0.M0 slot 0 on bstwin://k0 may be incomplete" in capsys.readouterr().err
    progress = json.loads((build / "flash-progress.json").read_text())["modules"]
    assert progress["L0.M0"]["status"] == "incomplete" and "L0.M1" not in progress


def test_auto_port(monkeypatch: pytest.MonkeyPatch) -> None:
    from bstool.flash import port as port_mod
    from bstool.flash.errors import PortError

    monkeypatch.setattr(port_mod, "usb_serial_ports", lambda: [])
    with pytest.raises(PortError, match="no USB-serial port found"):
        port_mod.resolve_auto()
    monkeypatch.setattr(port_mod, "usb_serial_ports", lambda: ["/dev/ttyUSB0"])
    assert port_mod.resolve_auto() == "/dev/ttyUSB0"
    monkeypatch.setattr(port_mod, "usb_serial_ports", lambda: ["/dev/ttyUSB0", "/dev/ttyUSB1"])
    with pytest.raises(PortError, match=r"2 USB-serial ports found \(/dev/ttyUSB0, /dev/ttyUSB1\)"):
        port_mod.resolve_auto()
    assert port_mod.resolve_auto(lambda ports: ports[1]) == "/dev/ttyUSB1"


def test_busy_port_is_reported() -> None:
    from bstool.flash.errors import PortError
    from bstool.flash.port import open_port
    from hil_mock.ptyendpoint import PtyEndpoint

    with PtyEndpoint(ProgrammingDevice()) as ep:
        first = open_port(ep.path)
        try:
            with pytest.raises(PortError, match="is busy"):
                open_port(ep.path)
        finally:
            first.close()


def test_bsx_target(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = _bsx(tmp_path)
    dev = twin("bsx")
    code = main(["flash", "-p", "bstwin://bsx", str(src), "--no-listen"])
    assert code == 0, capsys.readouterr().err
    assert dev.sessions >= 1


@pytest.mark.slow
def test_cli_over_a_served_pty(tmp_path: Path) -> None:
    """`python -m hil_mock serve` in one process, `bstool flash --port /dev/pts/N` in another."""
    import os
    import subprocess
    import sys

    build = make_build(tmp_path / "b", [ModuleId(3, 2)], slots=2)
    eeproms = tmp_path / "eeproms"
    serve = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hil_mock",
            "serve",
            "--modules",
            "3.2",
            "--timing",
            "none",
            "--eeprom-dir",
            str(eeproms),
            "--runner",
            "scan",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert serve.stdout is not None
        _label, path = serve.stdout.readline().split()
        env = {**os.environ, "BSTOOL_FLASH_FAST": "1"}
        done = subprocess.run(
            [sys.executable, "-m", "bstool", "flash", "--port", path, str(build)],
            capture_output=True,
            text=True,
            env=env,
            timeout=60,
        )
        assert done.returncode == 0, done.stderr
        assert "no modem lines" in done.stderr
        assert "module L3.M2 runs controller 3fa9c0d1" in done.stdout
    finally:
        serve.terminate()
        serve.wait(timeout=5)
    stored = (eeproms / "L3.M2.eeprom").read_bytes()
    assert stored[:2048] == slot_image("L3.M2", 0) and stored[2048:4096] == slot_image("L3.M2", 1)


def test_ports_file_with_one_module(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    build = make_build(tmp_path / "b", [ModuleId(0, 0), ModuleId(4, 5)])
    dev = twin("pm")
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({"4.5": "bstwin://pm"}))
    assert main(["flash", "--ports", str(ports), "-m", "4.5", str(build)]) == 0
    assert dev.eeprom.slot(0) == slot_image("L4.M5", 0)
    assert main(["flash", "--ports", str(ports), "-m", "0.0", str(build)]) == 2
    assert "names no port for L0.M0" in capsys.readouterr().err


def test_port_failure_mid_upload_is_a_message(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import serial

    from bstool.flash.session import Programmer

    build = make_build(tmp_path / "b", [ModuleId(0, 0)])
    twin("gone")

    def unplugged(self: Programmer, record: bytes) -> None:
        raise serial.SerialException("device reports readiness to read but returned no data")

    monkeypatch.setattr(Programmer, "send_record", unplugged)
    assert main(["flash", "-p", "bstwin://gone", str(build)]) == 4
    err = capsys.readouterr().err
    assert "the port bstwin://gone failed while flashing L0.M0 slot 0" in err and "Hint:" in err


def test_a_controller_without_module_is_refused_before_compiling(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import bstool.compile

    def boom(*_a: object, **_k: object) -> None:
        raise AssertionError("compiled before saying what is missing")

    monkeypatch.setattr(bstool.compile, "compile_controller", boom)
    from conftest import traced_controller

    code = main(["flash", "--port", "bstwin://nobody", str(traced_controller("ca1d"))])
    assert code == 2
