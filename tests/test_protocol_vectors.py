"""Both sides of the programming protocol against the transcripts in protocol/vectors/.

The host (bstool.flash) talks to a scripted port that plays the stamp's part and checks every
byte and reset; the device (hil_mock) is fed the host's part and must answer byte for byte.
The stored JSON must equal what protocol/vectors/make_vectors.py writes (run it to refresh).
"""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path
from typing import Any

import pytest

from bstool.flash import errors as flash_errors
from bstool.flash.session import Programmer, Timing
from hil_mock.progdevice import Faults, ProgrammingDevice
from hil_mock.runners import AnnounceRunner

ROOT = Path(__file__).resolve().parents[1]
VECTORS_FILE = ROOT / "protocol" / "vectors" / "programming.json"
VECTORS: list[dict[str, Any]] = json.loads(VECTORS_FILE.read_text())["vectors"]
IDS = [v["name"] for v in VECTORS]
TIMING = Timing(reply=0.0, ack=0.0, reset_hold=0, break_after_reset=0, settle=0, announce=0.05)


def test_vectors_file_is_up_to_date() -> None:
    spec = importlib.util.spec_from_file_location(
        "make_vectors", VECTORS_FILE.with_name("make_vectors.py")
    )
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.render() == VECTORS_FILE.read_text(), "run protocol/vectors/make_vectors.py"


class ScriptPort:
    """A pyserial-like port that plays the device side of one transcript, strictly."""

    def __init__(self, steps: list[dict[str, str]]) -> None:
        self.steps = list(steps)
        self.pos = 0  # next step
        self.expect = b""  # host bytes still expected in the current step
        self.answer = b""
        self.inbox = bytearray()
        self.port = "script://"
        self.baudrate = 9600
        self.timeout: float | None = 0.0
        self._dtr = False
        self._brk = False
        self._reset_phase = 0  # 1 dtr+brk, 2 dtr off with brk, 3 brk off = reset done
        self.resets_seen = 0

    # line changes: recognise the programming reset of §2
    @property
    def dtr(self) -> bool:
        return self._dtr

    @dtr.setter
    def dtr(self, on: bool) -> None:
        self._dtr = on
        self._line_event()

    @property
    def break_condition(self) -> bool:
        return self._brk

    @break_condition.setter
    def break_condition(self, on: bool) -> None:
        self._brk = on
        self._line_event()

    def _line_event(self) -> None:
        if self._dtr and self._brk:
            self._reset_phase = 1
        elif self._reset_phase == 1 and not self._dtr and self._brk:
            self._reset_phase = 2
        elif self._reset_phase == 2 and not self._dtr and not self._brk:
            self._reset_phase = 0
            self.resets_seen += 1

    def write(self, data: bytes) -> int:
        for b in data:
            if not self.expect:
                self._next_step()
            assert b == self.expect[0], (
                f"step {self.pos - 1}: host sent {b:02X}, transcript expects {self.expect[0]:02X}"
            )
            self.expect = self.expect[1:]
            if not self.expect:
                self.inbox += self.answer
        return len(data)

    def _next_step(self) -> None:
        assert self.pos < len(self.steps), "host sent more than the transcript"
        step = self.steps[self.pos]
        self.pos += 1
        if "reset" in step:
            assert self.resets_seen > 0, f"step {self.pos - 1}: transcript expects a reset"
            self.resets_seen = 0
            self._next_step()
            return
        assert self.resets_seen == 0, f"step {self.pos - 1}: unexpected reset"
        self.expect = bytes.fromhex(step["host"])
        self.answer = bytes.fromhex(step["device"])

    def read(self, n: int = 1) -> bytes:
        out = bytes(self.inbox[:n])
        del self.inbox[:n]
        return out

    @property
    def in_waiting(self) -> int:
        return len(self.inbox)

    def reset_input_buffer(self) -> None:
        self.inbox.clear()

    def done(self) -> bool:
        return self.pos == len(self.steps) and not self.expect


def _run_host(vector: dict[str, Any], prog: Programmer) -> Any:
    call = vector["call"]
    if call["op"] == "connect":
        return prog.connect()
    records = [bytes.fromhex(r) for r in call["records"]]
    prog.upload_slot(call["slot"], records)
    return prog.listen() if call.get("listen") else None


@pytest.mark.parametrize("vector", VECTORS, ids=IDS)
def test_host_follows_vector(vector: dict[str, Any]) -> None:
    port = ScriptPort(vector["steps"])
    prog = Programmer(port, name="script", timing=TIMING)  # type: ignore[arg-type]
    expect = vector["expect"]
    if expect.get("ok"):
        result = _run_host(vector, prog)
        if "version" in expect:
            assert result == expect["version"]
        if "announcement" in expect:
            assert list(result) == expect["announcement"]
    else:
        error_type = getattr(flash_errors, expect["error"])
        with pytest.raises(error_type) as info:
            _run_host(vector, prog)
        assert re.search(expect["match"], str(info.value)), str(info.value)
        assert info.value.hint
    assert port.done(), f"host stopped at step {port.pos} of {len(port.steps)}"


def make_device(config: dict[str, Any]) -> ProgrammingDevice:
    raw = config["faults"]
    faults = Faults(
        flip_rx={int(k): v for k, v in raw.get("flip_rx", {}).items()},
        drop_rx=set(raw.get("drop_rx", [])),
        nak={int(k): v for k, v in raw.get("nak", {}).items()},
        nak_block={int(k): v for k, v in raw.get("nak_block", {}).items()},
        hang_at_rx=raw.get("hang_at_rx"),
        dead_at_rx=raw.get("dead_at_rx"),
        brownout_at_rx=raw.get("brownout_at_rx"),
    )
    runner = AnnounceRunner(config["announce"].encode()) if "announce" in config else None
    return ProgrammingDevice(
        model=config["model"], version=config["version"], faults=faults, runner=runner
    )


@pytest.mark.parametrize("vector", VECTORS, ids=IDS)
def test_device_follows_vector(vector: dict[str, Any]) -> None:
    device = make_device(vector["device"])
    out = bytearray()
    device.attach(lambda data, t, echo: out.extend(data), lambda: 0.0)
    for i, step in enumerate(vector["steps"]):
        if "reset" in step:
            device.set_dtr(True, 0)
            device.set_break(True, 0)
            device.set_dtr(False, 0)
            device.set_break(False, 0)
            out.clear()  # the host flushes its input after the reset
            continue
        for b in bytes.fromhex(step["host"]):
            device.receive(b, 0)
        assert out.hex() == step["device"], f"step {i} ({step['note']})"
        out.clear()
    if "eeprom" in vector:
        slot = device.eeprom.slot(vector["eeprom"]["slot"])
        for block, data in vector["eeprom"]["blocks"].items():
            b = int(block)
            assert slot[b * 16 : b * 16 + 16].hex() == data
