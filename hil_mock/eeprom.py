"""The BS2sx EEPROM: 8 slots of 2048 bytes, optionally kept in a file like real EEPROM.

With a ``path`` the whole 16 KiB are loaded at start (a missing file = erased EEPROM) and
written back atomically after every change, so a twin keeps its programs across restarts.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

from bstool import fileio

SLOTS = 8
SLOT_SIZE = 2048
BLOCK_SIZE = 16
ERASED = 0x00  # what an unwritten byte reads as in the twin (a choice: docs/flash.md)


class Eeprom:
    """16 KiB of slot memory. Thread-safe; ``version`` counts writes (for watchers)."""

    def __init__(self, path: str | os.PathLike[str] | None = None) -> None:
        self.path = Path(path) if path is not None else None
        self._data = bytearray([ERASED]) * (SLOTS * SLOT_SIZE)
        self._lock = threading.Lock()
        self.version = 0
        if self.path is not None and self.path.exists():
            raw = self.path.read_bytes()
            if len(raw) != len(self._data):
                raise ValueError(
                    f"{self.path}: EEPROM file has {len(raw)} bytes, expected {len(self._data)}"
                )
            self._data[:] = raw

    def slot(self, n: int) -> bytes:
        """A copy of slot ``n``'s 2048 bytes."""
        self._check_slot(n)
        with self._lock:
            return bytes(self._data[n * SLOT_SIZE : (n + 1) * SLOT_SIZE])

    def read(self, slot: int, address: int) -> int:
        self._check_slot(slot)
        return self._data[slot * SLOT_SIZE + (address % SLOT_SIZE)]

    def write(self, slot: int, address: int, data: bytes) -> None:
        """Write ``data`` at ``address`` of ``slot`` (must stay inside the slot)."""
        self._check_slot(slot)
        if address < 0 or address + len(data) > SLOT_SIZE:
            raise ValueError(f"write of {len(data)} bytes at {address} leaves slot {slot}")
        with self._lock:
            start = slot * SLOT_SIZE + address
            self._data[start : start + len(data)] = data
            self.version += 1
            snapshot = bytes(self._data) if self.path is not None else None
        if snapshot is not None and self.path is not None:
            fileio.write_bytes(self.path, snapshot)

    def write_block(self, slot: int, block: int, data: bytes) -> None:
        """One download record's 16 bytes into block ``block`` (0-127)."""
        if len(data) != BLOCK_SIZE:
            raise ValueError(f"a block is {BLOCK_SIZE} bytes, got {len(data)}")
        self.write(slot, block * BLOCK_SIZE, data)

    def load_slot(self, slot: int, image: bytes) -> None:
        """Put a whole 2048-byte image into ``slot`` (tests and previews)."""
        if len(image) != SLOT_SIZE:
            raise ValueError(f"a slot image is {SLOT_SIZE} bytes, got {len(image)}")
        self.write(slot, 0, image)

    @staticmethod
    def _check_slot(n: int) -> None:
        if not 0 <= n < SLOTS:
            raise ValueError(f"slot {n} out of range 0..{SLOTS - 1}")
