"""Constants and pure helpers of the BS2sx programming protocol (see protocol/programming.md).

Shared by the host (bstool.flash) and the device side (hil_mock), so both read the same
numbers. Nothing here touches a port.
"""

from __future__ import annotations

from dataclasses import dataclass

BAUD = 9600
BITS_PER_BYTE = 10  # 8N1: start + 8 data + stop
SLOTS = 8
SLOT_SIZE = 2048
BLOCK_SIZE = 16
BLOCKS = SLOT_SIZE // BLOCK_SIZE  # 128
RECORD_SIZE = 18  # header + 16 EEPROM bytes + check
HEADER_BASE = 0x80  # header = 0x80 + block number
END_OF_SESSION = 0x00

BS2SX_ID = 0x58  # 'X'
#: Reply byte to 'X' -> firmware version of a BS2sx.
BS2SX_VERSIONS = {0x58: "1.0", 0x59: "1.1", 0x5A: "1.2", 0x5B: "1.3"}

ACK_OK = 0x00
ACK_CHECKSUM = 0x01
ACK_EEPROM = 0x02
ACK_MEANINGS = {
    ACK_OK: "ok",
    ACK_CHECKSUM: "checksum or communication error",
    ACK_EEPROM: "EEPROM write failed",
}

# Reset into programming mode (seconds). protocol/programming.md "Reset".
T_RESET_HOLD = 0.002  # DTR (reset) and break together, at least this long
T_BREAK_AFTER_RESET = 0.036  # keep the break after DTR drops
T_SETTLE = 0.020  # after the break clears, before the first byte

# Host timeouts (seconds) at 9600 baud; bstool.flash scales nothing, tests pass shorter ones.
T_REPLY = 0.25  # echo + identification reply, slot echo
T_ACK = 1.0  # record acknowledgement after the last echo byte


def byte_time(baud: int = BAUD) -> float:
    """Seconds one 8N1 byte occupies the wire."""
    return BITS_PER_BYTE / baud


def line_limit_seconds(n_bytes: int, baud: int = BAUD) -> float:
    """The physical lower bound for sending ``n_bytes`` one way."""
    return n_bytes * BITS_PER_BYTE / baud


def checksum(body: bytes) -> int:
    """The check byte that makes ``body + check`` sum to 0 mod 256."""
    return (-sum(body)) & 0xFF


def make_record(block: int, data: bytes) -> bytes:
    """Build the 18-byte download record for EEPROM block ``block`` (0-127)."""
    if not 0 <= block < BLOCKS:
        raise ValueError(f"block {block} out of range 0..{BLOCKS - 1}")
    if len(data) != BLOCK_SIZE:
        raise ValueError(f"a block holds {BLOCK_SIZE} bytes, got {len(data)}")
    body = bytes([HEADER_BASE + block]) + bytes(data)
    return body + bytes([checksum(body)])


def record_ok(record: bytes) -> bool:
    """True when ``record`` is 18 bytes, has a header byte and sums to 0 mod 256."""
    return len(record) == RECORD_SIZE and record[0] >= HEADER_BASE and sum(record) % 256 == 0


def record_block(record: bytes) -> int:
    return record[0] - HEADER_BASE


def records_for_image(eeprom: bytes, blocks: list[int] | None = None) -> list[bytes]:
    """Records for the given blocks of a 2048-byte image (default: every block not all zero)."""
    if len(eeprom) != SLOT_SIZE:
        raise ValueError(f"a slot image has {SLOT_SIZE} bytes, got {len(eeprom)}")
    if blocks is None:
        blocks = [b for b in range(BLOCKS) if any(eeprom[b * BLOCK_SIZE : (b + 1) * BLOCK_SIZE])]
    return [make_record(b, eeprom[b * BLOCK_SIZE : (b + 1) * BLOCK_SIZE]) for b in blocks]


@dataclass(frozen=True)
class StampModel:
    """How one BASIC Stamp model answers identification (protocol/programming.md)."""

    name: str
    challenge: bytes  # bytes the host sends, each echoed
    replies: bytes  # expected reply after each challenge byte but the last (BS2 only)
    versions: dict[int, str]  # final reply byte -> "<variant> v<version>"


#: Identification of the other stamps, used only to name a stamp that is not a BS2sx.
OTHER_MODELS: tuple[StampModel, ...] = (
    StampModel("BS2", b"BS2\x00", bytes([0xBE, 0xAD, 0xCE]), {}),
    StampModel("BS2e", b"e", b"", {0x65: "BS2e v1.0"}),
    StampModel(
        "BS2p",
        b"P",
        b"",
        {
            **{0x70 + i: f"BS2p24 v1.{i}" for i in range(4)},
            **{0x50 + i: f"BS2p40 v1.{i}" for i in range(4)},
        },
    ),
    StampModel(
        "BS2pe",
        b"I",
        b"",
        {
            **{0x69 + i: f"BS2pe24 v1.{i}" for i in range(3)},
            **{0x49 + i: f"BS2pe40 v1.{i}" for i in range(3)},
        },
    ),
)


def describe_other(model: StampModel, reply: int) -> str:
    """Human name of a non-BS2sx stamp from its final reply byte."""
    if model.name == "BS2":
        return f"BS2 (version byte ${reply:02X})"
    return model.versions.get(reply, f"{model.name} (reply ${reply:02X})")
