"""The host against the twin's device side with injected faults, over bstwin:// and a pty.

In every case the upload either ends with exactly the image on the device or raises the
right DeviceError — never success with a different image.
"""

from __future__ import annotations

import itertools
import random
from typing import Any

import pytest
import serial
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hil_mock  # noqa: F401
from bstool.errors import DeviceError
from bstool.flash import FAST, Programmer, Timing
from bstool.flash import errors as E
from bstool.flash.port import open_port
from bstool.wire import programming as P
from hil_mock.progdevice import Faults, ProgrammingDevice
from hil_mock.ptyendpoint import PtyEndpoint
from hil_mock.urlhandler import add_twin, remove_twin

_rng = random.Random(7)
IMAGE = bytes(_rng.randrange(256) for _ in range(P.SLOT_SIZE))
RECORDS = P.records_for_image(IMAGE, list(range(P.BLOCKS)))
_names = itertools.count()
# ptys go through the kernel and two pump threads: more slack than FAST against a loaded CI
PTY_TIMING = Timing(reply=0.2, ack=0.5, reset_hold=0, break_after_reset=0, settle=0)


# rx byte index of record r's byte k in a first clean session: 'X', slot, then records
def rx(record: int, k: int = 0) -> int:
    return 2 + record * P.RECORD_SIZE + k


def upload_twin(device: ProgrammingDevice, *, slot: int = 0, query: str = "") -> Any:
    name = f"faults-{next(_names)}"
    add_twin(name, device)
    ser = open_port(f"bstwin://{name}{query}", timeout=0.05)
    try:
        return Programmer(ser, timing=FAST).upload_slot(slot, RECORDS)
    finally:
        ser.close()
        remove_twin(name)


GOOD_CASES = {
    "flip_rx": Faults(flip_rx={rx(10, 3): 0x04}),
    "flip_rx_header": Faults(flip_rx={rx(20, 0): 0x80}),
    "flip_echo": Faults(flip_tx={rx(30, 7) + 1: 0x40}),
    "drop": Faults(drop_rx={rx(40, 17)}),
    "drop_header": Faults(drop_rx={rx(41, 0)}),
    "nak_once": Faults(nak={5: 1}),
    "nak_eeprom_once": Faults(nak={127: 2}),
    "brownout": Faults(brownout_at_rx=rx(64, 9)),
    "two_faults": Faults(drop_rx={rx(3, 2)}, flip_rx={rx(90, 1): 1}),
}


@pytest.mark.parametrize("name", list(GOOD_CASES))
def test_recoverable_fault_gives_exact_image(name: str) -> None:
    device = ProgrammingDevice(faults=GOOD_CASES[name])
    result = upload_twin(device, slot=3)
    assert device.eeprom.slot(3) == IMAGE
    assert result.retries >= 1 and result.records == P.BLOCKS


def test_clean_upload_has_no_retries() -> None:
    device = ProgrammingDevice()
    result = upload_twin(device, slot=7)
    assert device.eeprom.slot(7) == IMAGE and result.retries == 0
    assert result.bytes_sent == 2 + P.BLOCKS * P.RECORD_SIZE + 1


BAD_CASES: dict[str, tuple[ProgrammingDevice, type[DeviceError], str]] = {
    "nak_always": (
        ProgrammingDevice(faults=Faults(nak_block={12: 2})),
        E.RecordRefusedError,
        r"record 13 of 128 \(block \$0C\) of slot 0: ack code 2 \(EEPROM write failed\)",
    ),
    "hang": (
        ProgrammingDevice(faults=Faults(hang_at_rx=rx(50, 5))),
        E.FlashTimeoutError,
        r"stopped answering at record 51 of 128",
    ),
    "power_lost": (
        ProgrammingDevice(faults=Faults(dead_at_rx=rx(70))),
        E.FlashTimeoutError,
        r"stopped answering at record 71 of 128",
    ),
    "wrong_model": (ProgrammingDevice(model="BS2pe40"), E.WrongStampError, r"BS2pe40 v1.0"),
    "bs2": (ProgrammingDevice(model="BS2"), E.WrongStampError, r"is a BS2 \(version"),
    "no_power": (ProgrammingDevice(faults=Faults(dead_at_rx=0)), E.NoEchoError, "nothing echoed"),
    "no_prog_mode": (
        ProgrammingDevice(faults=Faults(hang_at_rx=0)),
        E.NoReplyError,
        "not in programming mode",
    ),
    "constant_noise": (
        ProgrammingDevice(faults=Faults(flip_rx={rx(8, k): 1 for k in range(0, 400, 18)})),
        E.EchoMismatchError,
        "echo differs at record 9",
    ),
}


@pytest.mark.parametrize("name", list(BAD_CASES))
def test_unrecoverable_fault_gives_its_message(name: str) -> None:
    device, error, message = BAD_CASES[name]
    with pytest.raises(error, match=message) as info:
        upload_twin(device)
    assert info.value.hint
    assert device.eeprom.slot(0) != IMAGE


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    flips=st.dictionaries(st.integers(0, 2400), st.integers(1, 255), max_size=4),
    echo_flips=st.dictionaries(st.integers(0, 2500), st.integers(1, 255), max_size=3),
    drops=st.sets(st.integers(0, 2400), max_size=3),
    naks=st.dictionaries(st.integers(0, 140), st.integers(1, 3), max_size=3),
    brownout=st.none() | st.integers(0, 2400),
)
def test_never_success_with_a_wrong_image(
    flips: dict[int, int],
    echo_flips: dict[int, int],
    drops: set[int],
    naks: dict[int, int],
    brownout: int | None,
) -> None:
    faults = Faults(
        flip_rx=flips, flip_tx=echo_flips, drop_rx=drops, nak=naks, brownout_at_rx=brownout
    )
    device = ProgrammingDevice(faults=faults)
    try:
        upload_twin(device)
    except DeviceError as exc:
        assert exc.hint
    else:
        assert device.eeprom.slot(0) == IMAGE


@pytest.mark.parametrize(
    "faults",
    [
        Faults(),
        Faults(flip_rx={rx(10, 3): 4}),
        Faults(flip_tx={rx(11, 3): 4}),
        Faults(drop_rx={rx(20, 5)}),
        Faults(nak={3: 1}),
        Faults(brownout_at_rx=rx(30, 8)),
    ],
    ids=["clean", "flip", "flip_echo", "drop", "nak", "brownout"],
)
def test_no_modem_lines_over_pty(faults: Faults, capsys: pytest.CaptureFixture[str]) -> None:
    device = ProgrammingDevice(faults=faults)
    with PtyEndpoint(device) as ep:
        ser = open_port(ep.path, timeout=0.05)
        logs: list[str] = []
        try:
            Programmer(ser, timing=PTY_TIMING, log=logs.append).upload_slot(1, RECORDS)
        finally:
            ser.close()
    assert device.eeprom.slot(1) == IMAGE
    assert any("no modem lines" in line for line in logs)


@pytest.mark.parametrize(
    ("faults", "model", "error"),
    [
        (Faults(dead_at_rx=rx(5)), "BS2sx", E.FlashTimeoutError),
        (Faults(hang_at_rx=rx(6)), "BS2sx", E.FlashTimeoutError),
        (Faults(nak_block={4: 2}), "BS2sx", E.RecordRefusedError),
        (Faults(), "BS2p24", E.WrongStampError),
    ],
    ids=["stops", "hangs", "nak_always", "wrong_model"],
)
def test_pty_failures(faults: Faults, model: str, error: type[DeviceError]) -> None:
    device = ProgrammingDevice(faults=faults, model=model)
    with PtyEndpoint(device) as ep:
        ser = open_port(ep.path, timeout=0.05)
        with pytest.raises(error):
            Programmer(ser, timing=FAST).upload_slot(0, RECORDS)
        ser.close()


def test_no_modem_url_over_bstwin_warns() -> None:
    device = ProgrammingDevice()
    logs: list[str] = []
    add_twin("nomodem", device)
    ser = serial.serial_for_url("bstwin://nomodem?modem=0", timeout=0.05)
    Programmer(ser, timing=FAST, log=logs.append).upload_slot(2, RECORDS[:4])
    ser.close()
    remove_twin("nomodem")
    assert device.eeprom.slot(2)[:64] == IMAGE[:64]
    assert sum("no modem lines" in line for line in logs) == 1


def test_socket_url_without_modem_lines() -> None:
    """``socket://host:port`` (e.g. ser2net on a bench computer) works, with one warning."""
    import socket
    import threading

    from hil_mock.line import Line

    device = ProgrammingDevice(reset_on_id=True, faults=Faults(drop_rx={rx(6, 2)}))
    line = Line(device)
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    stop = threading.Event()

    def serve() -> None:
        conn, _ = server.accept()
        conn.settimeout(0.01)
        with conn:
            while not stop.is_set():
                try:
                    data = conn.recv(4096)
                    if not data:
                        break
                    line.write(data)
                except TimeoutError:
                    pass
                out = line.read(line.in_waiting(), 0)
                if out:
                    conn.sendall(out)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    logs: list[str] = []
    ser = open_port(f"socket://127.0.0.1:{port}", timeout=0.05)
    try:
        Programmer(ser, timing=FAST, log=logs.append).upload_slot(6, RECORDS[:10])
    finally:
        ser.close()
        stop.set()
        thread.join(timeout=2)
        server.close()
    assert device.eeprom.slot(6)[:160] == IMAGE[:160]
    assert sum("no modem lines" in m for m in logs) == 1
