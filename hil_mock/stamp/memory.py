"""RAM, scratchpad, pins and EEPROM access of one virtual BS2sx (bs2sx.md §1, §4).

RAM is 32 bytes; words, bytes, nibbles and bits overlay it little-endian: word k = bytes 2k
(low) and 2k+1, nibble 2j = low nibble of byte j, bit i = bit i mod 8 of byte i div 8. Word 0
is INS, 1 OUTS, 2 DIRS. INS is kept up to date in bytes 0-1 from the pins: a pin whose DIR bit
is 1 reads its OUT latch, an input pin reads the level the outside world drives
(:attr:`Memory.external`). Writing INS has no effect (it is recomputed at once).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

from bstool.tokenizer import tokens as T

from .errors import StampFault

RAM_BYTES = 32
RUNNING_SLOT_ADDRESS = T.SCRATCHPAD_BYTES - 1  # 63: read-only, low nibble = running slot


class Memory:
    """The stamp's volatile state: 32 B RAM, 64 B scratchpad, external pin levels."""

    __slots__ = ("external", "ram", "scratch")

    def __init__(self) -> None:
        self.ram = bytearray(RAM_BYTES)
        self.scratch = bytearray(T.SCRATCHPAD_BYTES)
        self.external = 0  # 16-bit levels driven from outside on input pins

    def clear(self) -> None:
        """Reset / power-up / download: RAM (and with it the pin directions) cleared."""
        self.ram[:] = bytes(RAM_BYTES)
        self.refresh_ins()

    # -- pins ---------------------------------------------------------------------------------
    @property
    def outs(self) -> int:
        return self.ram[2] | self.ram[3] << 8

    @property
    def dirs(self) -> int:
        return self.ram[4] | self.ram[5] << 8

    def refresh_ins(self) -> None:
        dirs = self.dirs
        ins = (self.outs & dirs) | (self.external & ~dirs & 0xFFFF)
        self.ram[0] = ins & 0xFF
        self.ram[1] = ins >> 8

    def pin_level(self, pin: int) -> int:
        """The level on pin 0-15 as INS reads it."""
        return ((self.ram[0] | self.ram[1] << 8) >> pin) & 1

    # -- overlays (slow, for tests and the twin; the interpreter inlines them) -----------------
    def word(self, k: int) -> int:
        return self.ram[2 * k] | self.ram[2 * k + 1] << 8

    def byte(self, j: int) -> int:
        return self.ram[j]

    def nib(self, n: int) -> int:
        return (self.ram[n >> 1] >> (4 * (n & 1))) & 15

    def bit(self, i: int) -> int:
        return (self.ram[i >> 3] >> (i & 7)) & 1

    def set_word(self, k: int, v: int) -> None:
        self.ram[2 * k] = v & 0xFF
        self.ram[2 * k + 1] = (v >> 8) & 0xFF

    def get_scratch(self, addr: int, slot: int) -> int:
        addr &= T.SCRATCHPAD_BYTES - 1
        if addr == RUNNING_SLOT_ADDRESS:
            return slot & 0x0F
        return self.scratch[addr]

    def put_scratch(self, addr: int, value: int) -> None:
        addr &= T.SCRATCHPAD_BYTES - 1
        if addr != RUNNING_SLOT_ADDRESS:  # location 63 is read-only
            self.scratch[addr] = value & 0xFF


@runtime_checkable
class SlotStore(Protocol):
    """What the interpreter needs from an EEPROM: whole-slot reads and single-byte writes."""

    def read_slot(self, slot: int) -> bytes: ...

    def write_byte(self, slot: int, addr: int, value: int) -> None: ...


class SimpleEeprom:
    """8 × 2048 bytes in memory: the minimal :class:`SlotStore` (tests, benches)."""

    def __init__(self, slots: Sequence[bytes] | None = None) -> None:
        self.slots = [bytearray(T.SLOT_BYTES) for _ in range(T.SLOTS)]
        for n, image in enumerate(slots or ()):
            self.load(n, image)

    def load(self, slot: int, image: bytes) -> None:
        if len(image) != T.SLOT_BYTES:
            raise StampFault(f"slot {slot} image has {len(image)} bytes, expected {T.SLOT_BYTES}")
        self.slots[slot][:] = image

    def read_slot(self, slot: int) -> bytes:
        return bytes(self.slots[slot])

    def write_byte(self, slot: int, addr: int, value: int) -> None:
        self.slots[slot][addr] = value & 0xFF


class _SequenceStore:
    """Adapts a sequence of 8 mutable byte buffers (or one 16 KiB buffer) to SlotStore."""

    def __init__(self, slots: Sequence[bytearray]) -> None:
        self.slots = slots

    def read_slot(self, slot: int) -> bytes:
        return bytes(self.slots[slot])

    def write_byte(self, slot: int, addr: int, value: int) -> None:
        self.slots[slot][addr] = value & 0xFF


class _SlotWriteStore:
    """Adapts hil_mock.eeprom.Eeprom-style objects: ``slot(n) -> bytes``,
    ``write(slot, address, data: bytes)``."""

    def __init__(self, obj: Any) -> None:
        self.obj = obj

    def read_slot(self, slot: int) -> bytes:
        return bytes(self.obj.slot(slot))

    def write_byte(self, slot: int, addr: int, value: int) -> None:
        self.obj.write(slot, addr, bytes([value & 0xFF]))


def as_slot_store(obj: object) -> SlotStore:
    """Accept a SlotStore, an object with ``slot(n)``/``write(slot, addr, data)``, 8 per-slot
    byte buffers, or one 16384-byte buffer."""
    if isinstance(obj, SlotStore):
        return obj
    if callable(getattr(obj, "slot", None)) and callable(getattr(obj, "write", None)):
        return _SlotWriteStore(obj)
    if isinstance(obj, bytes | bytearray | memoryview) and len(obj) == T.SLOTS * T.SLOT_BYTES:
        buf = obj if isinstance(obj, bytearray) else bytearray(obj)
        views = [memoryview(buf)[n * T.SLOT_BYTES : (n + 1) * T.SLOT_BYTES] for n in range(8)]
        return _SequenceStore(views)  # type: ignore[arg-type]
    if isinstance(obj, Sequence) and len(obj) == T.SLOTS:
        return _SequenceStore([s if isinstance(s, bytearray) else bytearray(s) for s in obj])
    raise StampFault(
        f"cannot use {type(obj).__name__} as an EEPROM",
        hint="pass an object with read_slot(n)/write_byte(n, addr, v), 8 slot buffers, "
        "or one 16384-byte buffer",
    )
