"""The token interpreter of one virtual BS2sx, on a virtual clock.

Design for the robot twin (docs/twin.md): a :class:`Stamp` executes one instruction per
:meth:`Stamp.step` (or many with :meth:`Stamp.run_until`) and keeps its own virtual time
``t`` in integer nanoseconds. Nothing blocks: SERIN puts the stamp in :attr:`Status.WAITING`
with a :class:`SerialWait` (pin, since, deadline); a scheduler that always advances the stamp
with the smallest :attr:`Stamp.horizon` either delivers a byte with :meth:`Stamp.deliver_byte`
or, once every other stamp has passed the deadline, calls :meth:`Stamp.expire_wait`. Outputs go
to a :class:`StampIO` (serial bytes with their start time, PULSOUT pulses with start and
width, pin changes); DEBUG bytes (pin 16) are also kept in :attr:`Stamp.debug`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from bstool.tokenizer import tokens as T

from . import timing
from .clock import StampClock, frame_received
from .codegen import TX_PC, WAIT_PC, Program, load_program
from .errors import NotInTwin, StampFault
from .memory import Memory, SlotStore, as_slot_store
from .serial import InputItem, make_input_item, output_bytes

GOSUB_DEPTH = 4  # BS2 family: GOSUBs nest 4 deep
NEVER = 1 << 62  # horizon of a stamp that will not act on its own


class Status(enum.Enum):
    RUNNING = "running"
    WAITING = "waiting"  # in SERIN, for a byte or its timeout
    ENDED = "ended"  # END: low-power sleep until reset
    STOPPED = "stopped"  # STOP: halted, outputs held


_RUNNING = Status.RUNNING
_WAITING = Status.WAITING


@dataclass
class SerialWait:
    """A stamp blocked in SERIN: it takes a byte whose start bit falls in [since, deadline)."""

    pin: int
    mode: int  # baudmode
    since: int  # ns: listening from
    deadline: int | None  # ns: timeout fires here (None = waits forever)


class StampIO:
    """The world seen by one stamp. Override in the twin; every method is a no-op here."""

    def serial_out(self, stamp: Stamp, pin: int, value: int, start_ns: int, mode: int) -> None:
        """One byte leaves on ``pin`` (16 = SOUT/DEBUG); its start bit begins at ``start_ns``
        and it lasts :func:`~hil_mock.stamp.timing.byte_ns` (mode)."""

    def pulse(self, stamp: Stamp, pin: int, start_ns: int, width_ns: int, level: int) -> None:
        """PULSOUT: ``pin`` is at ``level`` from ``start_ns`` for ``width_ns``."""

    def pins_changed(self, stamp: Stamp, t_ns: int) -> None:
        """OUTS or DIRS changed at ``t_ns`` (read them from ``stamp.memory``)."""


class RecordingIO(StampIO):
    """Keeps every serial byte and pulse (tests, small runs)."""

    def __init__(self) -> None:
        self.serial: list[tuple[int, int, int, int]] = []  # (pin, value, start_ns, mode)
        self.pulses: list[tuple[int, int, int, int]] = []  # (pin, start_ns, width_ns, level)

    def serial_out(self, stamp: Stamp, pin: int, value: int, start_ns: int, mode: int) -> None:
        self.serial.append((pin, value, start_ns, mode))

    def pulse(self, stamp: Stamp, pin: int, start_ns: int, width_ns: int, level: int) -> None:
        self.pulses.append((pin, start_ns, width_ns, level))


class Stamp:
    """One BS2sx: EEPROM slots, RAM/scratchpad/pins, the running program and its clock."""

    def __init__(
        self,
        eeprom: object,
        *,
        io: StampIO | None = None,
        name: str = "stamp",
        clock: StampClock | None = None,
    ) -> None:
        self.eeprom: SlotStore = as_slot_store(eeprom)
        self.io = io if io is not None else RecordingIO()
        self.name = name
        self.memory = Memory()
        self.ram = self.memory.ram
        self.t = 0
        self.debug = bytearray()
        self.instructions = 0  # executed steps (SEROUT bytes count one each)
        self.brk = False  # set by an instruction to leave the inner run loop
        self.event = False  # set when a serial byte went out (run_until returns)
        self.rx_missed = 0  # bytes offered while not listening on that pin (no receive buffer)
        self.rx_mismatched = 0  # bytes lost to a bit-time mismatch beyond the UART's tolerance
        self.set_clock(clock or StampClock())  # issue 13 §2: its timing model is the clock's
        self.reset()

    def set_clock(self, clock: StampClock) -> None:
        """This stamp's timing factors (:mod:`.clock`); the translated code reads ``_ins`` and
        ``_pause_ns``."""
        self.clock = clock
        self._ins = clock.instruction
        self._pause_ns = clock.pause_ns

    # ---- life cycle ---------------------------------------------------------------------------
    def reset(self, slot: int = 0) -> None:
        """Reset / power-up: RAM cleared (all pins inputs), slot ``slot`` from its start.
        The scratchpad keeps its contents (only power loss clears it: use ``power_cycle``)."""
        self.memory.clear()
        self._last_pins = (0, 0)
        self.status = Status.RUNNING
        self.wait: SerialWait | None = None
        self._gosubs: list[int] = []
        self._rx: list[Any] = []
        self._rx_item: InputItem | None = None
        self._enter_slot(slot)

    def power_cycle(self) -> None:
        self.memory.scratch[:] = bytes(len(self.memory.scratch))
        self.reset(0)

    def _enter_slot(self, slot: int) -> None:
        self.slot = slot & (T.SLOTS - 1)
        self._image = bytearray(self.eeprom.read_slot(self.slot))
        self.program: Program = load_program(bytes(self._image))
        self._code = self.program.code
        self.pc = self.program.start
        self._gosubs = []

    @property
    def time(self) -> float:
        """Virtual time in seconds."""
        return self.t / 1e9

    @property
    def horizon(self) -> int:
        """The earliest virtual time (ns) at which this stamp acts on its own."""
        status = self.status
        if status is _RUNNING:
            return self.t
        w = self.wait
        if status is _WAITING and w is not None and w.deadline is not None:
            return w.deadline
        return NEVER

    # ---- execution ------------------------------------------------------------------------------
    def step(self) -> Status:
        """Execute one instruction (one byte of a SEROUT); no-op unless RUNNING."""
        if self.status is Status.RUNNING:
            self.brk = False
            self.pc = self._code[self.pc](self)
            self.instructions += 1
        return self.status

    def run_until(self, limit_ns: int, max_steps: int = 1 << 60) -> Status:
        """Run while RUNNING and ``t < limit_ns``; return early after any serial byte out (so a
        scheduler can deliver it) or when the stamp blocks/ends. Executes at least one step if
        RUNNING."""
        n = 0
        while self.status is Status.RUNNING and n < max_steps:
            code = self._code
            pc = self.pc
            self.brk = False
            self.event = False
            while True:
                pc = code[pc](self)
                n += 1
                if self.brk or self.t >= limit_ns or n >= max_steps:
                    break
            self.pc = pc
            if self.event or self.t >= limit_ns:
                break
        self.instructions += n
        return self.status

    def run(self, seconds: float | None = None, max_steps: int = 10_000_000) -> Status:
        """Run alone (no serial input) until END/STOP/SERIN or ``seconds`` of virtual time."""
        limit = NEVER if seconds is None else self.t + int(seconds * 1e9)
        steps = 0
        while self.status is Status.RUNNING and self.t < limit and steps < max_steps:
            before = self.instructions
            self.run_until(limit, max_steps - steps)
            steps += self.instructions - before
        return self.status

    # ---- serial input -------------------------------------------------------------------------
    def deliver_byte(
        self,
        pin: int,
        value: int,
        start_ns: int,
        mode: int | None = None,
        tx_bit_ns: float | None = None,
    ) -> bool:
        """Offer a byte whose start bit begins at ``start_ns`` on ``pin``, sent at baudmode
        ``mode`` with bit time ``tx_bit_ns`` (default: the nominal one of ``mode``; mode None:
        this stamp's own). It is taken only if the stamp is in SERIN on that pin since at most
        ``start_ns`` and before the deadline (no receive buffer), and the two bit times are
        within the UART's tolerance (:func:`.clock.frame_received`). Returns True if taken."""
        w = self.wait
        if self.status is not Status.WAITING or w is None or w.pin != pin:
            self.rx_missed += 1
            return False
        if start_ns < w.since or (w.deadline is not None and start_ns >= w.deadline):
            self.rx_missed += 1
            return False
        clock = self.clock
        if tx_bit_ns is None and mode is not None:
            tx_bit_ns = timing.byte_ns(mode) / timing.BITS_PER_BYTE
        if tx_bit_ns is not None and not frame_received(tx_bit_ns, clock.bit_ns(w.mode)):
            self.rx_mismatched += 1
            return False  # garbage: counted as lost
        self.t = start_ns + clock.rx_done_ns(w.mode, tx_bit_ns)
        self.instructions += 1
        item = self._rx_item
        assert item is not None
        if item.feed(self, value & 0xFF):
            self._next_rx_item()
        if self.status is Status.WAITING:
            w.since = self.t
            if w.deadline is not None:
                w.deadline = self.t + self._rx_timeout
        return True

    def expire_wait(self) -> None:
        """SERIN timeout: the clock jumps to the deadline and the program goes to its label."""
        w = self.wait
        if self.status is not Status.WAITING or w is None or w.deadline is None:
            return
        self.t = max(self.t, w.deadline)
        self.wait = None
        self._rx_item = None
        self.status = Status.RUNNING
        self.pc = self._rx_label

    def set_input(self, pin: int, level: int) -> None:
        """Drive input pin 0-15 from outside (seen in INS while the pin is an input)."""
        m = 1 << pin
        ext = self.memory.external
        self.memory.external = ext | m if level else ext & ~m
        self.memory.refresh_ins()

    # ---- helpers called by translated code ----------------------------------------------------
    def _pins(self) -> None:
        mem = self.memory
        mem.refresh_ins()
        now = (mem.outs, mem.dirs)
        if now != self._last_pins:
            self._last_pins = now
            self.io.pins_changed(self, self.t)

    def _notimpl(self, name: str, addr: int) -> int:
        raise NotInTwin(name, where=f"{self.name} slot {self.slot} bit {addr}")

    def _bad_image(self, addr: int) -> int:
        raise StampFault(
            f"{self.name}: slot {self.slot} holds no valid program at bit {addr} "
            "(the token stream runs off the slot)",
            hint="download a program into this slot (an erased or foreign image cannot run)",
        )

    def _gosub(self, ident: int) -> None:
        self._gosubs.append(ident)
        if len(self._gosubs) > GOSUB_DEPTH:
            del self._gosubs[0]  # the oldest return is lost, as on the stamp's 4-entry stack

    def _return(self) -> int:
        if not self._gosubs:
            raise StampFault(
                f"{self.name}: RETURN without GOSUB (slot {self.slot})",
                hint="check the program's GOSUB/RETURN pairing",
            )
        returns = self.program.decoded.returns
        ident = self._gosubs.pop()
        if ident >= len(returns):
            raise StampFault(f"{self.name}: GOSUB id {ident} has no return-table entry")
        return returns[ident]

    def _run(self, slot: int) -> int:
        self.t += self.clock.run_ns
        self._enter_slot(slot & 7)
        self.brk = True
        return self.pc

    def _end(self, addr: int) -> int:
        self.status = Status.ENDED
        self.brk = True
        return addr

    def _stop(self, addr: int) -> int:
        self.status = Status.STOPPED
        self.brk = True
        return addr

    def _read(self, addr: int) -> int:
        return self._image[addr & (T.SLOT_BYTES - 1)]

    def _write(self, addr: int, value: int) -> None:
        addr &= T.SLOT_BYTES - 1
        self._image[addr] = value & 0xFF
        self.eeprom.write_byte(self.slot, addr, value & 0xFF)
        self.t += timing.EEPROM_WRITE_NS

    def _get(self, addr: int) -> int:
        return self.memory.get_scratch(addr, self.slot)

    def _put(self, addr: int, value: int) -> None:
        self.memory.put_scratch(addr, value)

    def _drive(self, pin: int, level: int | None) -> None:
        """Make ``pin`` an output at ``level`` (None: input)."""
        r = self.ram
        j, m = (2 if pin < 8 else 3), 1 << (pin & 7)
        if level is None:
            r[j + 2] &= 255 ^ m
        else:
            r[j + 2] |= m
            r[j] = r[j] | m if level else r[j] & (255 ^ m)
        self._pins()

    def _pulsout(self, pin: int, units: int) -> None:
        pin &= 15
        level = 1 - ((self.memory.outs >> pin) & 1)
        self._drive(pin, 1 - level)
        width = self.clock.pulse_ns(units)
        self.io.pulse(self, pin, self.t, width, level)
        self.t += width

    def _serout(self, pin: int, mode: int, pace: int, items: tuple[Any, ...], nxt: int) -> int:
        data = output_bytes(items, self.ram)
        if pin < 16:
            self._drive(pin & 15, 0 if mode & 0x4000 else 1)  # idle level (inverted: low)
        if not data:
            return nxt
        self._tx = data
        self._tx_i = 0
        self._tx_pin = pin if pin < 16 else T.SERIAL_PIN
        self._tx_mode = mode
        self._tx_gap = pace * self._pause_ns + self.clock.item_gap_ns
        self._tx_next = nxt
        return TX_PC

    def _tx_step(self) -> int:
        i = self._tx_i
        b = self._tx[i]
        if self._tx_pin == T.SERIAL_PIN:
            self.debug.append(b)
        self.io.serial_out(self, self._tx_pin, b, self.t, self._tx_mode)
        self.t += self.clock.byte_ns(self._tx_mode)
        self._tx_i = i + 1
        self.brk = True
        self.event = True
        if i + 1 < len(self._tx):
            self.t += self._tx_gap
            return TX_PC
        return self._tx_next

    def _serin(
        self,
        pin: int,
        mode: int,
        timeout: int | None,
        tlabel: int | None,
        plabel: int | None,
        items: tuple[Any, ...],
        nxt: int,
    ) -> int:
        if pin < 16:
            self._drive(pin & 15, None)
        else:
            pin = T.SERIAL_PIN
        self._rx = list(items)
        self._rx_next = nxt
        self._rx_label = tlabel if tlabel is not None else nxt
        self._rx_timeout = self.clock.timeout_ns(timeout or 0)
        deadline = self.t + self._rx_timeout if timeout is not None else None
        self.wait = SerialWait(pin, mode, self.t, deadline)
        self.status = Status.WAITING
        self._rx_item = None
        self._next_rx_item()
        self.brk = True
        return self.pc if self.status is Status.RUNNING else WAIT_PC

    def _next_rx_item(self) -> None:
        """Activate the next SERIN item (skipping items that need no byte); finish if none."""
        while self._rx:
            kind, fmt, write = self._rx.pop(0)
            item = make_input_item(kind, fmt, write, self)
            if not item.done:
                self._rx_item = item
                return
        self._rx_item = None
        self.wait = None
        self.status = Status.RUNNING
        self.pc = self._rx_next
