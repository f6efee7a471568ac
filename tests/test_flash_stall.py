"""A stamp that stalls mid-upload is reported as what was seen — no answer for N ms — and
never as line noise, even when a late byte reaches the host after the stall (issue 16, 12)."""

from __future__ import annotations

import itertools
from typing import Any

import pytest

import hil_mock  # noqa: F401
from bstool.flash import FAST, Programmer
from bstool.flash import errors as E
from bstool.flash import protocol as P
from bstool.flash.port import open_port
from hil_mock.progdevice import Faults, ProgrammingDevice
from hil_mock.urlhandler import add_twin, remove_twin

IMAGE = bytes(range(256)) * (P.SLOT_SIZE // 256)
RECORDS = P.records_for_image(IMAGE, list(range(P.BLOCKS)))
_names = itertools.count()


class LateByte:
    """The port, except that the first read after the n-th input flush returns one byte that
    arrived late (the last echo byte of the record the stamp stalled in)."""

    _own = ("_ser", "_flushes", "_late_after", "_pending")

    def __init__(self, ser: Any, late_after: int) -> None:
        self._ser = ser
        self._flushes = 0
        self._late_after = late_after
        self._pending = b""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ser, name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name in self._own:
            object.__setattr__(self, name, value)
        else:
            setattr(self._ser, name, value)

    def reset_input_buffer(self) -> None:
        self._ser.reset_input_buffer()
        self._flushes += 1
        if self._flushes == self._late_after:
            self._pending = b"\x00"

    def read(self, n: int = 1) -> bytes:
        if self._pending:
            data, self._pending = self._pending, b""
            return data
        return bytes(self._ser.read(n))


@pytest.mark.parametrize("late_after", [None, 2, 3, 4])
@pytest.mark.parametrize("fault", ["hang", "dead"])
def test_a_stall_is_no_answer_not_line_noise(fault: str, late_after: int | None) -> None:
    at = 2 + 5 * P.RECORD_SIZE + 7  # inside record 6
    faults = Faults(hang_at_rx=at) if fault == "hang" else Faults(dead_at_rx=at)
    name = f"stall-{next(_names)}"
    add_twin(name, ProgrammingDevice(faults=faults))
    ser = open_port(f"bstwin://{name}", timeout=0.05)
    port = ser if late_after is None else LateByte(ser, late_after)
    try:
        with pytest.raises(E.FlashTimeoutError) as info:
            Programmer(port, timing=FAST).upload_slot(0, RECORDS)  # type: ignore[arg-type]
    finally:
        ser.close()
        remove_twin(name)
    message = str(info.value)
    assert "line noise" not in message and "line noise" not in (info.value.hint or "")
    assert "stopped answering at record 6 of 128" in message
    assert any(w in message for w in ("no answer", "nothing echoed", "no stamp answers"))
