"""hil_mock's device side: EEPROM store, protocol state machine, line timing, bstwin:// URL, pty."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial

import hil_mock  # noqa: F401  (registers bstwin://)
from bstool.wire import programming as P
from hil_mock.eeprom import Eeprom
from hil_mock.line import Line
from hil_mock.progdevice import Faults, ProgrammingDevice
from hil_mock.ptyendpoint import PtyEndpoint
from hil_mock.runners import AnnounceRunner, ScanRunner
from hil_mock.urlhandler import add_twin, get_twin, remove_twin

ANNOUNCE = b"bstool L1.M4 0123abcd\r"


def _session(dev: ProgrammingDevice) -> bytearray:
    out = bytearray()
    dev.attach(lambda data, t, echo: out.extend(data), lambda: 0.0)
    dev.set_dtr(True, 0)
    dev.set_break(True, 0)
    dev.set_dtr(False, 0)
    dev.set_break(False, 0)
    return out


def _send(dev: ProgrammingDevice, data: bytes) -> None:
    for b in data:
        dev.receive(b, 0)


def test_eeprom_persists_across_instances(tmp_path: Path) -> None:
    path = tmp_path / "m.eeprom"
    e = Eeprom(path)
    e.write_block(3, 7, bytes(range(16)))
    again = Eeprom(path)
    assert again.slot(3)[112:128] == bytes(range(16))
    assert again.slot(0) == bytes(2048)
    path.write_bytes(b"short")
    with pytest.raises(ValueError, match="expected 16384"):
        Eeprom(path)
    with pytest.raises(ValueError):
        e.write(0, 2040, bytes(16))


def test_session_writes_record_and_runs_slot0() -> None:
    runner = AnnounceRunner(ANNOUNCE)
    dev = ProgrammingDevice(runner=runner)
    out = _session(dev)
    _send(dev, b"X")
    assert out == b"XZ"
    out.clear()
    rec = P.make_record(5, bytes(range(16)))
    _send(dev, b"\x02" + rec + b"\x00")
    assert bytes(out) == b"\x02" + rec + b"\x00" + b"\x00" + ANNOUNCE
    assert dev.eeprom.slot(2)[80:96] == bytes(range(16))
    assert runner.starts == 1 and dev.state == "running"


def test_reset_without_break_runs_and_ignores_id() -> None:
    runner = AnnounceRunner(ANNOUNCE)
    dev = ProgrammingDevice(runner=runner)
    out = bytearray()
    dev.attach(lambda data, t, echo: out.extend(data), lambda: 0.0)
    dev.set_dtr(True, 0)
    dev.set_dtr(False, 0)
    assert bytes(out) == ANNOUNCE
    out.clear()
    _send(dev, b"X")
    assert out == b"X"  # hardware echo, no answer: not in programming mode


def test_bad_checksum_is_refused_and_not_written() -> None:
    dev = ProgrammingDevice()
    out = _session(dev)
    _send(dev, b"X\x00")
    rec = bytearray(P.make_record(0, bytes([9] * 16)))
    rec[-1] ^= 1
    out.clear()
    _send(dev, bytes(rec))
    assert out[-1] == P.ACK_CHECKSUM
    assert dev.eeprom.slot(0)[:16] == bytes(16)


@pytest.mark.parametrize(
    ("model", "challenge", "answer"),
    [("BS2", b"BS2\x00", b"\xbe\xad\xce\x10"), ("BS2e", b"e", b"e"), ("BS2pe24", b"I", b"i")],
)
def test_other_models_answer_only_their_id(model: str, challenge: bytes, answer: bytes) -> None:
    dev = ProgrammingDevice(model=model)
    out = _session(dev)
    _send(dev, b"X")
    assert out == b"X"
    out.clear()
    for c, a in zip(challenge, answer, strict=True):
        dev.receive(c, 0)
        assert out[-2:] == bytes([c, a])


def test_unknown_model_rejected() -> None:
    with pytest.raises(ValueError, match="unknown stamp model"):
        ProgrammingDevice(model="BS1")


def test_reset_on_id_starts_a_session_without_lines() -> None:
    dev = ProgrammingDevice(reset_on_id=True)
    out = bytearray()
    dev.attach(lambda data, t, echo: out.extend(data), lambda: 0.0)
    _send(dev, b"X\x01")  # running -> X starts a session
    assert out == b"XZ\x01"
    out.clear()
    _send(dev, b"X")  # mid-session (between records) X restarts identification
    assert out == b"XZ"


def test_flip_tx_and_noise_faults() -> None:
    dev = ProgrammingDevice(faults=Faults(flip_tx={1: 0x01}))
    out = _session(dev)
    _send(dev, b"X")
    assert out == b"X" + bytes([0x5A ^ 1])
    noisy = ProgrammingDevice(faults=Faults(noise=1.0, seed=1))
    out = _session(noisy)
    _send(noisy, b"X")
    assert out[0] != ord("X") and bin(out[0] ^ ord("X")).count("1") == 1


def test_virtual_line_time_is_wire_time() -> None:
    """In virtual time a record costs 18 byte times plus the ack byte (echo rides along)."""
    dev = ProgrammingDevice()
    line = Line(dev, timing="virtual")
    line.set_dtr(True)
    line.set_break(True)
    line.set_dtr(False)
    line.set_break(False)
    line.write(b"X")
    assert line.read(2, 1.0) == b"XZ"
    line.write(b"\x00")
    assert line.read(1, 1.0) == b"\x00"
    t0 = line.now()
    rec = P.make_record(0, bytes(16))
    line.write(rec)
    assert line.read(19, 1.0) == rec + b"\x00"
    assert line.now() - t0 == pytest.approx(19 * 10 / 9600)
    assert line.read(1, 0.5) == b""  # a timeout costs virtual time, not wall time
    assert line.now() - t0 == pytest.approx(19 * 10 / 9600 + 0.5)


def test_real_line_paces_bytes() -> None:
    dev = ProgrammingDevice(reset_on_id=True)
    line = Line(dev, timing="real")
    start = time.monotonic()
    line.write(b"X" * 20)
    assert len(line.read(21, 1.0)) == 21
    assert time.monotonic() - start >= 20 * 10 / 9600 * 0.95


def test_bstwin_url_roundtrip_and_options(tmp_path: Path) -> None:
    remove_twin("dev-url")
    port = serial.serial_for_url(
        f"bstwin://dev-url?model=BS2e&eeprom={tmp_path / 'e.bin'}", timeout=0.05
    )
    assert get_twin("dev-url").model == "BS2e"
    port.dtr = True
    port.break_condition = True
    port.dtr = False
    port.break_condition = False
    port.write(b"e")
    assert port.read(2) == b"ee"
    port.close()
    nomodem = serial.serial_for_url("bstwin://dev-url?modem=0", timeout=0.05)
    with pytest.raises(serial.SerialException):
        nomodem.dtr = False
    nomodem.close()
    for bad in ("bstwin://", "bstwin://x?timing=warp", "bstwin://x?colour=red"):
        with pytest.raises(serial.SerialException):
            serial.serial_for_url(bad)
    remove_twin("dev-url")


def test_pty_endpoint_echoes_and_programs() -> None:
    dev = add_twin("pty-dev", ProgrammingDevice(runner=ScanRunner()))
    with PtyEndpoint(dev) as ep:
        port = serial.serial_for_url(ep.path, timeout=0.5)
        port.write(b"X\x04")
        assert port.read(3) == b"XZ\x04"
        rec = P.make_record(1, b"A" * 16)
        port.write(rec)
        assert port.read(19) == rec + b"\x00"
        port.close()
    assert dev.eeprom.slot(4)[16:32] == b"A" * 16
    remove_twin("pty-dev")


@pytest.mark.slow
def test_serve_prints_pty_paths(tmp_path: Path) -> None:
    ports = tmp_path / "ports.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hil_mock",
            "serve",
            "--modules",
            "0.0,1.2",
            "--timing",
            "none",
            "--ports-file",
            str(ports),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().split() for _ in range(2)]
        assert [label for label, _ in lines] == ["L0.M0", "L1.M2"]
        assert all(os.path.exists(path) for _, path in lines)
        port = serial.serial_for_url(lines[1][1], timeout=1.0)
        port.write(b"X")
        assert port.read(2) == b"XZ"
        port.close()
        assert ports.exists()
    finally:
        proc.terminate()
        proc.wait(timeout=5)
