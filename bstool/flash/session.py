"""The host side of one programming session with one stamp (protocol/programming.md).

:class:`Programmer` resets the stamp into programming mode, identifies it, selects a slot,
sends records checking the echo of every byte and each acknowledgement, and ends the session.
:meth:`Programmer.upload_slot` adds the recovery: a clean NAK is answered by resending the
record; anything else (short or wrong echo, lost ack, stray bytes) by a fresh reset and a
resume at that record, since a reset discards a partial record and sent blocks are kept.
"""

from __future__ import annotations

import errno
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from bstool.flash.errors import (
    EchoMismatchError,
    FlashTimeoutError,
    NoEchoError,
    NoReplyError,
    RecordRefusedError,
    WrongStampError,
)
from bstool.flash.port import NO_MODEM_SCHEMES, scheme
from bstool.wire import announce
from bstool.wire import programming as P


@dataclass
class Timing:
    """Waits and retry budgets. Defaults follow the protocol; tests pass short ones."""

    reply: float = P.T_REPLY
    ack: float = P.T_ACK
    reset_hold: float = P.T_RESET_HOLD
    break_after_reset: float = P.T_BREAK_AFTER_RESET
    settle: float = P.T_SETTLE
    attempts: int = 3  # connect attempts, each with its own reset
    record_tries: int = 5  # tries of one record before giving up
    resyncs: int = 8  # resets allowed in one slot's upload
    announce: float = 2.0  # listening for the start-up line
    sleep: Callable[[float], None] = field(default=time.sleep, repr=False)


FAST = Timing(reply=0.05, ack=0.1, reset_hold=0.0, break_after_reset=0.0, settle=0.0, announce=0.2)


@dataclass(frozen=True)
class Progress:
    """Reported after every acknowledged record."""

    slot: int
    done: int
    total: int
    bytes_sent: int


@dataclass
class SlotResult:
    slot: int
    records: int
    bytes_sent: int  # every byte the host wrote for this slot, retries included
    seconds: float
    retries: int


class _Trouble(Exception):
    """One record went wrong; ``resync`` says whether a reset is needed before retrying."""

    def __init__(self, kind: str, detail: str, *, resync: bool, code: int | None = None):
        super().__init__(detail)
        self.kind = kind
        self.detail = detail
        self.resync = resync
        self.code = code


def _hex(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


class Programmer:
    """One open port to one stamp. ``log`` gets human lines, ``trace`` hex dumps."""

    def __init__(
        self,
        ser: serial.Serial,
        *,
        name: str | None = None,
        timing: Timing | None = None,
        log: Callable[[str], None] | None = None,
        trace: Callable[[str], None] | None = None,
    ) -> None:
        self.ser = ser
        self.name = name or str(ser.port)
        self.timing = timing or Timing()
        self.log = log or (lambda _msg: None)
        self.trace = trace
        self.version: str | None = None
        self.bytes_sent = 0
        self.modem_lines = scheme(self.name) not in NO_MODEM_SCHEMES
        self._warned = False

    # -- raw I/O --------------------------------------------------------------------------
    def _write(self, data: bytes) -> None:
        if self.trace:
            self.trace(f"{self.name} > {_hex(data)}")
        self.ser.write(data)
        self.bytes_sent += len(data)

    def _read(self, n: int, timeout: float) -> bytes:
        self.ser.timeout = timeout
        data = bytes(self.ser.read(n))
        if self.trace and data:
            self.trace(f"{self.name} < {_hex(data)}")
        return data

    def _drain(self) -> None:
        self.ser.reset_input_buffer()

    # -- lines ----------------------------------------------------------------------------
    def _no_modem_lines(self, exc: Exception | None = None) -> None:
        self.modem_lines = False
        if not self._warned:
            self._warned = True
            why = f" ({exc})" if exc else ""
            self.log(
                f"warning: {self.name} has no modem lines{why}: cannot reset the stamp; "
                "it must already be waiting in programming mode (the twin does)"
            )

    def _set_lines(self, dtr: bool | None = None, brk: bool | None = None) -> bool:
        if not self.modem_lines:
            self._no_modem_lines()
            return False
        try:
            if dtr is not None:
                self.ser.dtr = dtr
            if brk is not None:
                self.ser.break_condition = brk
        except (OSError, serial.SerialException) as exc:
            if getattr(exc, "errno", None) not in (errno.ENOTTY, errno.EINVAL, None):
                raise
            self._no_modem_lines(exc)
            return False
        return True

    def reset_to_programming(self) -> None:
        """DTR and break together, DTR drops, break held, break clears, settle, flush."""
        t = self.timing
        if self.trace:
            self.trace(f"{self.name} reset: DTR+BREAK")
        if self._set_lines(dtr=True, brk=True):
            t.sleep(t.reset_hold)
            self._set_lines(dtr=False)
            t.sleep(t.break_after_reset)
            self._set_lines(brk=False)
            t.sleep(t.settle)
        self._drain()

    def reset_to_run(self) -> bool:
        """A plain reset pulse (no break): the stamp runs slot 0. False without modem lines."""
        if not self._set_lines(dtr=True, brk=False):
            return False
        self.timing.sleep(max(self.timing.reset_hold, 0.001))
        self._set_lines(dtr=False)
        return True

    # -- identification -------------------------------------------------------------------
    def _challenge(self, model_bytes: bytes, expect: bytes) -> tuple[str, int | None]:
        """Send the id bytes; (outcome, last reply), outcome ok/noecho/badecho/noreply/badreply."""
        final: int | None = None
        for i, b in enumerate(model_bytes):
            self._write(bytes([b]))
            echo = self._read(1, self.timing.reply)
            if not echo:
                return ("noecho" if i == 0 else "noreply"), None
            if echo[0] != b:
                return "badecho", None
            reply = self._read(1, self.timing.reply)
            if not reply:
                return "noreply", None
            if i < len(expect) and reply[0] != expect[i]:
                return "badreply", reply[0]
            final = reply[0]
        return "ok", final

    def identify_once(self) -> tuple[str, int | None]:
        """Reset and send 'X' once; ('ok', version byte) on a BS2sx."""
        self.reset_to_programming()
        outcome, reply = self._challenge(bytes([P.BS2SX_ID]), b"")
        if outcome == "ok" and reply not in P.BS2SX_VERSIONS:
            outcome = "badreply"
        return outcome, reply

    def connect(self) -> str:
        """Identify a BS2sx in up to ``attempts`` tries, each redoing the reset; its version."""
        outcomes: list[str] = []
        replies: list[int] = []
        for attempt in range(self.timing.attempts):
            if attempt:
                self.log(
                    f"{self.name}: no BS2sx answer ({outcomes[-1]}), "
                    f"retrying (attempt {attempt + 1}/{self.timing.attempts})"
                )
            outcome, reply = self.identify_once()
            if outcome == "ok" and reply is not None:
                if self.version is None:
                    self.log(f"{self.name}: connected to a BS2sx v{P.BS2SX_VERSIONS[reply]}")
                self.version = P.BS2SX_VERSIONS[reply]
                return self.version
            outcomes.append(outcome)
            if reply is not None:
                replies.append(reply)
        if all(o == "noecho" for o in outcomes):
            raise NoEchoError(
                f"nothing echoed on {self.name} after {len(outcomes)} attempts",
                hint="check the module's power, the cable, and that this is its port",
            )
        silent = outcomes.count("noecho")
        if silent:  # a stall: silence, plus a late or stray byte in another attempt
            raise NoEchoError(
                f"no answer on {self.name} for {self.timing.reply * 1000:.0f} ms in {silent} of "
                f"{len(outcomes)} attempts (a stray byte in the others)",
                hint="check the module's power, the cable, and that this is its port",
            )
        other = self._probe_others()
        if other:
            raise WrongStampError(
                f"the stamp on {self.name} is a {other}, not a BS2sx",
                hint="bstool programs BS2sx modules only: check the module on this cable",
            )
        if replies:
            raise WrongStampError(
                f"unknown answer ${replies[-1]:02X} to the BS2sx identification on {self.name}",
                hint="not a BS2sx, or line noise: check the cable and retry",
            )
        if "noreply" in outcomes:
            hint = "the reset did not put it in programming mode: check the cable carries DTR"
            if not self.modem_lines:
                hint = "this port cannot reset the stamp (no modem lines): use a serial cable"
            raise NoReplyError(
                f"{self.name} echoes but no stamp answers: not in programming mode", hint=hint
            )
        raise EchoMismatchError(
            f"the echo on {self.name} differs from what was sent (line noise)",
            hint="check the cable, its ground and its length",
        )

    def _probe_others(self) -> str | None:
        """Try the other stamps' identification to name what is there."""
        for model in P.OTHER_MODELS:
            self.reset_to_programming()
            outcome, reply = self._challenge(model.challenge, model.replies)
            if outcome == "ok" and reply is not None:
                return P.describe_other(model, reply)
            if outcome == "badreply" and model.name == "BS2":
                continue
        return None

    # -- slot and records -----------------------------------------------------------------
    def select_slot(self, slot: int) -> None:
        if not 0 <= slot < P.SLOTS:
            raise ValueError(f"slot {slot} out of range 0..{P.SLOTS - 1}")
        self._write(bytes([slot]))
        echo = self._read(1, self.timing.reply)
        if echo != bytes([slot]):
            got = _hex(echo) or "nothing"
            raise _Trouble("slot", f"slot byte {slot} echoed as {got}", resync=True)

    def send_record(self, record: bytes) -> None:
        """Send one record; raise _Trouble unless the echo is exact and the ack is 0."""
        if self.ser.in_waiting:
            stray = self._read(self.ser.in_waiting, 0)
            raise _Trouble("stray", f"stray bytes before the record: {_hex(stray)}", resync=True)
        self._write(record)
        wire = P.byte_time(self.ser.baudrate or P.BAUD) * P.RECORD_SIZE
        echo = self._read(P.RECORD_SIZE, wire + self.timing.reply)
        if len(echo) < P.RECORD_SIZE:
            kind = "noecho" if not echo else "short"
            waited = (wire + self.timing.reply) * 1000
            raise _Trouble(
                kind,
                f"{len(echo)} of {P.RECORD_SIZE} bytes echoed, then no answer for {waited:.0f} ms",
                resync=True,
            )
        ack = self._read(1, self.timing.ack)
        if not ack:
            waited = self.timing.ack * 1000
            detail = f"no acknowledgement: no answer for {waited:.0f} ms"
            raise _Trouble("noack", detail, resync=True)
        if echo != record:
            at = next(i for i in range(P.RECORD_SIZE) if echo[i] != record[i])
            raise _Trouble(
                "mismatch",
                f"byte {at} sent as ${record[at]:02X} came back as ${echo[at]:02X}",
                resync=bool(self.ser.in_waiting),
            )
        if ack[0] != P.ACK_OK:
            meaning = P.ACK_MEANINGS.get(ack[0], "unknown code")
            raise _Trouble("nak", f"code {ack[0]} ({meaning})", resync=False, code=ack[0])

    def end_session(self) -> None:
        self._write(bytes([P.END_OF_SESSION]))
        echo = self._read(1, self.timing.reply)
        if echo != bytes([P.END_OF_SESSION]):
            self.log(f"warning: end-of-session byte echoed as {_hex(echo) or 'nothing'}")

    def upload_slot(
        self,
        slot: int,
        records: list[bytes],
        progress: Callable[[Progress], None] | None = None,
        *,
        connected: bool = False,
    ) -> SlotResult:
        """One full session for one slot, with retries; raises a DeviceError subclass on failure."""
        start_time = time.monotonic()
        start_bytes = self.bytes_sent
        total = len(records)
        retries = resyncs = tries = 0
        if not connected:
            self.connect()
        self._select_or_fail(slot)
        i = 0
        while i < total:
            try:
                self.send_record(records[i])
            except _Trouble as trouble:
                tries += 1
                retries += 1
                block = P.record_block(records[i])
                where = f"record {i + 1} of {total} (block ${block:02X}) of slot {slot}"
                if tries >= self.timing.record_tries or (
                    trouble.resync and resyncs >= self.timing.resyncs
                ):
                    raise self._give_up(trouble, where, i) from None
                self.log(f"{where}: {trouble.detail}; retrying")
                if trouble.resync:
                    resyncs += 1
                    self._resync(slot, where)
                continue
            i += 1
            tries = 0
            if progress:
                progress(Progress(slot, i, total, self.bytes_sent - start_bytes))
        self.end_session()
        return SlotResult(
            slot, total, self.bytes_sent - start_bytes, time.monotonic() - start_time, retries
        )

    def _select_or_fail(self, slot: int) -> None:
        try:
            self.select_slot(slot)
        except _Trouble as trouble:
            self._resync(slot, f"slot {slot} selection ({trouble.detail})")

    def _resync(self, slot: int, where: str) -> None:
        """Reset, identify and select the slot again; a dead stamp becomes a timeout error."""
        for _ in range(self.timing.attempts):
            try:
                self.connect()
                self.select_slot(slot)
                return
            except (NoEchoError, NoReplyError) as exc:
                raise FlashTimeoutError(
                    f"timeout: the stamp on {self.name} stopped answering at {where} "
                    f"({exc.message})",
                    hint="check power and cable; run the same command again to resume",
                ) from None
            except _Trouble:
                continue
        raise FlashTimeoutError(
            f"timeout: could not resume {where} on {self.name}",
            hint="check power and cable; run the same command again to resume",
        )

    def _give_up(self, trouble: _Trouble, where: str, index: int) -> Exception:
        if trouble.kind == "nak" and trouble.code is not None:
            return RecordRefusedError(
                f"the stamp refused {where}: ack {trouble.detail}",
                code=trouble.code,
                record=index,
                hint="code 1: line noise or a bad image; code 2: the stamp's EEPROM may be worn",
            )
        if trouble.kind == "mismatch":
            return EchoMismatchError(
                f"echo differs at {where}: {trouble.detail} (line noise)",
                hint="check the cable, its ground and its length, then run again",
            )
        return FlashTimeoutError(
            f"timeout at {where} on {self.name}: {trouble.detail}",
            hint="check power and cable; run the same command again to resume",
        )

    # -- after the upload -----------------------------------------------------------------
    def listen(self, timeout: float | None = None) -> tuple[int, int, str] | None:
        """Wait for the start-up announcement; (leg, module, hash8) or None."""
        deadline = time.monotonic() + (self.timing.announce if timeout is None else timeout)
        buf = b""
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            chunk = self._read(1, min(left, 0.05))
            if not chunk:
                continue
            buf = (buf + chunk)[-64:]
            found = announce.find(buf)
            if found:
                return found.module.leg, found.module.module, found.hash8
