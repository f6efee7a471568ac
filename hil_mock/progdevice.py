"""The device side of the BS2sx programming protocol (protocol/programming.md), with faults.

:class:`ProgrammingDevice` is a pure state machine driven by timestamped events from a
transport (:class:`hil_mock.line.Line` for the ``bstwin://`` URL and the pty):
``receive(byte, t)``, ``set_dtr(on, t)``, ``set_break(on, t)``. It answers through the
``send(data, t, echo)`` callback the transport attaches. Echo is modelled as the hardware
echo of the module's serial circuit: every byte is sent back as it arrives, whatever the
chip does, unless the module has no power.

After a session ends (or a reset without break) the stamp runs slot 0 through a pluggable
:class:`Runner` (the token interpreter, or a fake that prints the start-up line), which may
emit bytes on the same port via ``emit``.
"""

from __future__ import annotations

import random
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from bstool.wire import programming as P
from hil_mock.eeprom import Eeprom


class Runner(Protocol):
    """Runs the program in slot 0 after a reset; ``emit`` sends bytes on the port (SOUT)."""

    def start(self, eeprom: Eeprom, emit: Callable[[bytes], None]) -> None: ...

    def stop(self) -> None: ...


RunnerFactory = Callable[[], Runner]
_default_runner_factory: RunnerFactory | None = None


def set_default_runner_factory(factory: RunnerFactory | None) -> None:
    """Choose the runner new devices get (the interpreter registers itself here)."""
    global _default_runner_factory
    _default_runner_factory = factory


def default_runner() -> Runner | None:
    return _default_runner_factory() if _default_runner_factory else None


@dataclass
class Faults:
    """Faults on demand. Byte indices count bytes arriving at the device (from 0, over the
    device's life); record indices count complete records the device has received."""

    flip_rx: dict[int, int] = field(default_factory=dict)  # rx index -> XOR mask
    flip_tx: dict[int, int] = field(default_factory=dict)  # tx index -> XOR mask (echo/reply)
    drop_rx: set[int] = field(default_factory=set)  # rx bytes lost on the way in
    nak: dict[int, int] = field(default_factory=dict)  # record index -> ack code, once
    nak_block: dict[int, int] = field(default_factory=dict)  # block -> ack code, every time
    hang_at_rx: int | None = None  # chip stops here for good; the hardware echo goes on
    dead_at_rx: int | None = None  # power lost here for good: not even an echo
    brownout_at_rx: int | None = None  # reset here (byte lost); the stamp then runs slot 0
    noise: float = 0.0  # probability that an arriving byte gets one random bit flipped
    seed: int = 0


#: The answer bytes of each model to its identification (protocol/programming.md).
MODEL_IDS: dict[str, tuple[bytes, bytes]] = {
    # model: (challenge, replies one per challenge byte)
    "BS2sx": (b"X", b"Z"),
    "BS2": (b"BS2\x00", bytes([0xBE, 0xAD, 0xCE, 0x10])),
    "BS2e": (b"e", b"e"),
    "BS2p24": (b"P", b"p"),
    "BS2p40": (b"P", b"P"),
    "BS2pe24": (b"I", b"i"),
    "BS2pe40": (b"I", b"I"),
}

RUNNING, HELD, WAIT_ID, WAIT_SLOT, RECORDS = "running", "held in reset", "id", "slot", "records"


class ProgrammingDevice:
    """One virtual stamp's serial side: echo, reset, identification, slots, records."""

    def __init__(
        self,
        eeprom: Eeprom | None = None,
        *,
        model: str = "BS2sx",
        version: int | None = None,
        faults: Faults | None = None,
        runner: Runner | None = None,
        write_time: float = 0.0,
        reset_on_id: bool = False,
        record_gap: float = 0.03,
    ) -> None:
        if model not in MODEL_IDS:
            raise ValueError(f"unknown stamp model {model!r}; one of {', '.join(MODEL_IDS)}")
        self.eeprom = eeprom if eeprom is not None else Eeprom()
        self.model = model
        challenge, replies = MODEL_IDS[model]
        if version is not None:
            replies = replies[:-1] + bytes([version])
        self._challenge, self._replies = challenge, replies
        self.faults = faults or Faults()
        self.runner = runner if runner is not None else default_runner()
        self.write_time = write_time  # seconds from the last record byte to its ack
        self.reset_on_id = reset_on_id  # no modem lines (pty): an id byte starts a session
        # without modem lines nothing else can abort a partial record: an idle line does
        self.record_gap = record_gap
        self._last_rx = 0.0
        self.state = RUNNING
        self.slot = 0
        self.rx_count = 0
        self.tx_count = 0
        self.records_received = 0
        self.sessions = 0
        self.log: list[str] = []  # what happened, for tests and the serve console
        self._id_pos = 0
        self._buf = bytearray()
        self._dtr = False
        self._break = False
        self._hung = False
        self._dead = False
        self._now = 0.0
        self._rng = random.Random(self.faults.seed)
        self._lock = threading.RLock()
        self._send: Callable[[bytes, float, bool], None] = lambda data, t, echo: None
        self._clock: Callable[[], float] = lambda: self._now

    # -- wiring ---------------------------------------------------------------------------
    def attach(
        self, send: Callable[[bytes, float, bool], None], clock: Callable[[], float]
    ) -> None:
        """Connect a transport: ``send(data, t, echo)`` and its clock."""
        with self._lock:
            self._send = send
            self._clock = clock

    def _out(self, data: bytes, t: float, *, echo: bool = False) -> None:
        out = bytearray(data)
        for i in range(len(out)):
            out[i] ^= self.faults.flip_tx.get(self.tx_count, 0)
            self.tx_count += 1
        self._send(bytes(out), t, echo)

    def _emit(self, data: bytes) -> None:
        """What a runner prints (DEBUG on SOUT)."""
        with self._lock:
            if self.state == RUNNING and not self._dead:
                self._out(data, max(self._clock(), self._now))

    # -- line events ----------------------------------------------------------------------
    def set_dtr(self, on: bool, t: float) -> None:
        """DTR drives ATN: high holds the chip in reset; on release it starts (see break)."""
        with self._lock:
            self._now = max(self._now, t)
            if on == self._dtr:
                return
            self._dtr = on
            if on:
                self._enter_reset()
            elif self._break:
                self._enter_programming()
            else:
                self._start_running("reset")

    def set_break(self, on: bool, t: float) -> None:
        with self._lock:
            self._now = max(self._now, t)
            self._break = on

    def power_cycle(self, t: float = 0.0) -> None:
        """Brown-out or power-up: RAM and the partial record are lost, slot 0 runs."""
        with self._lock:
            self._now = max(self._now, t)
            self._enter_reset()
            self._start_running("power-up")

    def _enter_reset(self) -> None:
        if self.runner is not None and self.state == RUNNING:
            self.runner.stop()
        self.state = HELD
        self._buf.clear()
        self._id_pos = 0

    def _enter_programming(self) -> None:
        self.state = WAIT_ID
        self._id_pos = 0
        self._buf.clear()
        self.log.append("programming mode")

    def _start_running(self, why: str) -> None:
        self.state = RUNNING
        self.log.append(f"run slot 0 ({why})")
        if self.runner is not None and not self._hung:
            self.runner.start(self.eeprom, self._emit)

    # -- bytes ----------------------------------------------------------------------------
    def receive(self, byte: int, t: float) -> None:
        """A byte arrived completely at time ``t``."""
        with self._lock:
            self._now = max(self._now, t)
            f = self.faults
            index = self.rx_count
            self.rx_count += 1
            if self._dead or (f.dead_at_rx is not None and index >= f.dead_at_rx):
                if not self._dead:
                    self.log.append(f"power lost at rx byte {index}")
                self._dead = True
                return
            if index in f.drop_rx:
                return
            if f.brownout_at_rx == index:
                self.log.append(f"brown-out at rx byte {index}")
                self.power_cycle(t)
                return
            byte ^= f.flip_rx.get(index, 0)
            if f.noise and self._rng.random() < f.noise:
                byte ^= 1 << self._rng.randrange(8)
            self._out(bytes([byte]), t, echo=True)
            if f.hang_at_rx is not None and index >= f.hang_at_rx:
                if not self._hung:
                    self.log.append(f"hung at rx byte {index}")
                    if self.runner is not None and self.state == RUNNING:
                        self.runner.stop()
                self._hung = True
            if self._hung or self.state == HELD:
                return
            if self.reset_on_id and self._buf and t - self._last_rx > self.record_gap:
                self.log.append(f"partial record dropped after {t - self._last_rx:.3f} s idle")
                self._buf.clear()
            self._last_rx = t
            self._handle(byte, t)

    def _handle(self, byte: int, t: float) -> None:
        if (
            self.reset_on_id
            and byte == self._challenge[0]
            and not self._buf
            and not (self.state == WAIT_ID and self._id_pos)
        ):
            # no modem lines: an identification byte outside a record starts a new session
            self._enter_reset()
            self._enter_programming()
        if self.state == RUNNING:
            return
        if self.state == WAIT_ID:
            if byte == self._challenge[self._id_pos]:
                self._out(self._replies[self._id_pos : self._id_pos + 1], t)
                self._id_pos += 1
                if self._id_pos == len(self._challenge):
                    self.state = WAIT_SLOT if self.model == "BS2sx" else WAIT_ID
                    self._id_pos = 0
            else:
                self._id_pos = 0
            return
        if self.state == WAIT_SLOT:
            if byte < P.SLOTS:
                self.slot = byte
                self.state = RECORDS
                self.sessions += 1
            return
        # RECORDS
        if not self._buf:
            if byte == P.END_OF_SESSION:
                self.log.append(f"end of session (slot {self.slot})")
                self._start_running("end of session")
            elif byte >= P.HEADER_BASE:
                self._buf.append(byte)
            return
        self._buf.append(byte)
        if len(self._buf) == P.RECORD_SIZE:
            record = bytes(self._buf)
            self._buf.clear()
            self._out(bytes([self._store(record)]), t + self.write_time)

    def _store(self, record: bytes) -> int:
        """Check and write one record; its ack code."""
        index = self.records_received
        self.records_received += 1
        block = P.record_block(record)
        if not P.record_ok(record):
            self.log.append(f"record {index}: checksum error")
            return P.ACK_CHECKSUM
        code = self.faults.nak.pop(index, None) or self.faults.nak_block.get(block)
        if code:
            self.log.append(f"record {index}: refused with code {code}")
            return code
        self.eeprom.write_block(self.slot, block, record[1:17])
        return P.ACK_OK
