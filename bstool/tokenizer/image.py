"""The 2048-byte EEPROM image of one slot and its download records.

The program is one bit stream that starts at byte $7FF and grows down (stream bit ``b`` is bit
``7 - b % 8`` of byte ``2047 - b // 8``, fields MSB first); DATA grows up from $000. Every byte
carries a flag saying what it holds so overlaps are caught and records can be chosen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bstool.tokenizer import tokens
from bstool.tokenizer.diagnostics import Failure

EMPTY, UNDEFINED_DATA, DEFINED_DATA, PROGRAM = 0, 1, 2, 3
TOTAL_BITS = tokens.SLOT_BYTES * 8
_SENT = bytes(1 if f & 2 else 0 for f in range(256))


@dataclass
class Image:
    eeprom: bytearray = field(default_factory=lambda: bytearray(tokens.SLOT_BYTES))
    flags: bytearray = field(default_factory=lambda: bytearray(tokens.SLOT_BYTES))
    # source (offset, length) of the DATA item that filled each byte (for error 124)
    data_source: dict[int, tuple[int, int]] = field(default_factory=dict)
    pos: int = 0  # next program bit

    def put_data(self, address: int, value: int, defined: bool, where: tuple[int, int]) -> None:
        if self.flags[address] & 3:
            raise Failure(115, *where)
        self.flags[address] = DEFINED_DATA if defined else UNDEFINED_DATA
        self.eeprom[address] = value & 0xFF
        self.data_source[address] = where

    def emit(self, nbits: int, value: int) -> None:
        """Append ``nbits`` low bits of ``value`` to the program stream (MSB first)."""
        if self.pos + nbits > TOTAL_BITS:
            raise Failure(127, -1)
        eeprom, flags = self.eeprom, self.flags
        pos = self.pos
        while nbits:
            byte = TOTAL_BITS // 8 - 1 - (pos >> 3)
            if flags[byte] & 3 in (UNDEFINED_DATA, DEFINED_DATA):
                raise Failure(124, *self.data_source.get(byte, (0, 0)))
            free = 8 - (pos & 7)  # bits left in this byte
            take = free if free < nbits else nbits
            nbits -= take
            eeprom[byte] |= ((value >> nbits) & ((1 << take) - 1)) << (free - take)
            flags[byte] |= PROGRAM
            pos += take
        self.pos = pos

    def emit_address(self, address: int) -> None:
        """A 14-bit code address: its low 3 bits, then the byte count (address // 8)."""
        self.emit(3, address)
        self.emit(11, address >> 3)

    def patch_address(self, at: int, address: int) -> None:
        here = self.pos
        self.pos = at
        try:
            self.emit_address(address)
        finally:
            self.pos = here

    def count(self, kind: int) -> int:
        """Bytes flagged ``kind`` (flags only ever hold 0-3)."""
        return self.flags.count(kind)

    def records(self) -> list[bytes]:
        """18-byte download records of every block holding program or defined DATA."""
        out: list[bytes] = []
        sent = self.flags.translate(_SENT)  # 1 where a byte holds program or defined DATA
        for block in range(tokens.SLOT_BYTES // tokens.BLOCK_BYTES):
            lo = block * tokens.BLOCK_BYTES
            if 1 not in sent[lo : lo + tokens.BLOCK_BYTES]:
                continue
            body = bytes([tokens.RECORD_HEADER_BASE + block]) + bytes(
                self.eeprom[lo : lo + tokens.BLOCK_BYTES]
            )
            out.append(body + bytes([-sum(body) & 0xFF]))
        return out
