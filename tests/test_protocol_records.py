"""Properties of the download record framing (protocol/programming.md §5)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bstool.flash.target import parse_packets
from bstool.wire import programming as P

blocks = st.integers(0, P.BLOCKS - 1)
data16 = st.binary(min_size=16, max_size=16)


@given(blocks, data16)
def test_record_round_trip(block: int, data: bytes) -> None:
    rec = P.make_record(block, data)
    assert len(rec) == P.RECORD_SIZE and P.record_ok(rec)
    assert sum(rec) % 256 == 0 and P.record_block(rec) == block and rec[1:17] == data


@given(blocks, data16, st.integers(0, P.RECORD_SIZE - 1), st.integers(0, 7))
def test_any_single_bit_flip_is_detected(block: int, data: bytes, at: int, bit: int) -> None:
    rec = bytearray(P.make_record(block, data))
    rec[at] ^= 1 << bit
    assert not P.record_ok(bytes(rec))


@given(st.binary(min_size=P.SLOT_SIZE, max_size=P.SLOT_SIZE))
def test_image_records_rebuild_the_image(image: bytes) -> None:
    records = P.records_for_image(image)
    rebuilt = bytearray(P.SLOT_SIZE)
    for rec in records:
        b = P.record_block(rec)
        rebuilt[b * 16 : b * 16 + 16] = rec[1:17]
    assert bytes(rebuilt) == image
    assert [P.record_block(r) for r in records] == sorted(P.record_block(r) for r in records)
    assert parse_packets(b"".join(records), "x") == records


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        P.make_record(128, bytes(16))
    with pytest.raises(ValueError):
        P.make_record(0, bytes(15))
    with pytest.raises(ValueError):
        P.records_for_image(bytes(10))
    assert P.line_limit_seconds(960) == pytest.approx(1.0)
    assert P.describe_other(P.OTHER_MODELS[2], 0x71) == "BS2p24 v1.1"
