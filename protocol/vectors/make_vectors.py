"""Write programming.json: transcripts of the BS2sx programming protocol (protocol/programming.md).

Built from the rules of the spec only (no bstool or hil_mock code), so both sides are tested
against an independent statement. Run: ``python protocol/vectors/make_vectors.py``; the test
``tests/test_protocol_vectors.py`` fails when the stored file is out of date.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

OUT = Path(__file__).with_name("programming.json")
X, V12 = 0x58, 0x5A  # identification byte; our twin's answer (v1.2)


def block_data(block: int) -> bytes:
    return bytes((block * 16 + i * 7) & 0xFF for i in range(16))


def record(block: int) -> bytes:
    body = bytes([0x80 + block]) + block_data(block)
    return body + bytes([(-sum(body)) & 0xFF])


class Transcript:
    """Steps plus a count of the bytes that reach the stamp (fault indices refer to it)."""

    def __init__(self) -> None:
        self.steps: list[dict[str, str]] = []
        self.rx = 0

    def reset(self) -> None:
        self.steps.append({"reset": "programming"})

    def say(self, host: bytes, device: bytes, note: str) -> None:
        self.steps.append({"host": host.hex(), "device": device.hex(), "note": note})
        self.rx += len(host)

    def identify(self, answer: int | None = V12) -> None:
        self.reset()
        reply = bytes([X]) + (bytes([answer]) if answer is not None else b"")
        self.say(bytes([X]), reply, "identify: echo, then the version")

    def slot(self, n: int) -> None:
        self.say(bytes([n]), bytes([n]), f"select slot {n}: echo only")

    def rec(self, block: int, *, ack: int | None = 0, echo: bytes | None = None) -> None:
        r = record(block)
        back = (r if echo is None else echo) + (bytes([ack]) if ack is not None else b"")
        self.say(r, back, f"record block {block}: 18 echo bytes, then the ack")

    def end(self, extra: bytes = b"") -> None:
        self.say(b"\x00", b"\x00" + extra, "end of session: echo; slot 0 runs")


def vector(
    name: str,
    description: str,
    t: Transcript,
    call: dict[str, Any],
    expect: dict[str, Any],
    *,
    faults: dict[str, Any] | None = None,
    model: str = "BS2sx",
    version: int = V12,
    eeprom: dict[str, Any] | None = None,
    announce: str | None = None,
) -> dict[str, Any]:
    device: dict[str, Any] = {"model": model, "version": version, "faults": faults or {}}
    if announce is not None:
        device["announce"] = announce
    out: dict[str, Any] = {
        "name": name,
        "description": description,
        "device": device,
        "steps": t.steps,
        "call": call,
        "expect": expect,
    }
    if eeprom is not None:
        out["eeprom"] = eeprom
    return out


def upload_call(slot: int, blocks: list[int], **extra: Any) -> dict[str, Any]:
    return {"op": "upload", "slot": slot, "records": [record(b).hex() for b in blocks], **extra}


def blocks(slot: int, bs: list[int]) -> dict[str, Any]:
    return {"slot": slot, "blocks": {str(b): block_data(b).hex() for b in bs}}


def build() -> list[dict[str, Any]]:
    vs = []

    t = Transcript()
    t.identify()
    vs.append(
        vector(
            "identify",
            "A BS2sx answers 'X' with its version.",
            t,
            {"op": "connect"},
            {"ok": True, "version": "1.2"},
        )
    )

    t = Transcript()
    t.identify()
    t.slot(0)
    for b in (0, 1, 127):
        t.rec(b)
    t.end()
    vs.append(
        vector(
            "upload_slot0",
            "Three records into slot 0, all acknowledged, then the end byte.",
            t,
            upload_call(0, [0, 1, 127]),
            {"ok": True},
            eeprom=blocks(0, [0, 1, 127]),
        )
    )

    t = Transcript()
    t.identify()
    t.slot(5)
    t.rec(3)
    t.end(b"bstool L2.M3 3fa9c0d1\r")
    vs.append(
        vector(
            "upload_slot5_announce",
            "One record into slot 5; after the end byte slot 0 runs and announces itself.",
            t,
            upload_call(5, [3], listen=True),
            {"ok": True, "announcement": [2, 3, "3fa9c0d1"]},
            eeprom=blocks(5, [3]),
            announce="bstool L2.M3 3fa9c0d1\r",
        )
    )

    # A flipped bit on the way in: the echo shows it, the checksum fails, the ack is $01.
    t = Transcript()
    t.identify()
    t.slot(0)
    flip_at = t.rx + 5
    bad = bytearray(record(0))
    bad[5] ^= 0x10
    t.rec(0, ack=1, echo=bytes(bad))
    t.rec(0)
    t.end()
    vs.append(
        vector(
            "flipped_bit_retry",
            "Byte 5 of the first record arrives with bit 4 flipped: echo differs, ack $01; "
            "the host resends the record at once.",
            t,
            upload_call(0, [0]),
            {"ok": True},
            faults={"flip_rx": {str(flip_at): 0x10}},
            eeprom=blocks(0, [0]),
        )
    )

    # A dropped byte: 17 echo bytes and no ack; the host resets and resumes at that record.
    t = Transcript()
    t.identify()
    t.slot(0)
    t.rec(0)
    drop_at = t.rx + 9
    r1 = record(1)
    t.say(r1, r1[:9] + r1[10:], "record block 1 with byte 9 lost: 17 echo bytes, no ack")
    t.identify()
    t.slot(0)
    t.rec(1)
    t.end()
    vs.append(
        vector(
            "dropped_byte_resume",
            "Byte 9 of the second record never reaches the stamp: short echo, no ack; the "
            "host resets, identifies, selects the slot and resumes at that record.",
            t,
            upload_call(0, [0, 1]),
            {"ok": True},
            faults={"drop_rx": [drop_at]},
            eeprom=blocks(0, [0, 1]),
        )
    )

    t = Transcript()
    t.identify()
    t.slot(0)
    for _ in range(5):
        t.rec(2, ack=2)
    vs.append(
        vector(
            "nak_eeprom",
            "The stamp refuses block 2 with code 2 every time: after 5 tries the host stops.",
            t,
            upload_call(0, [2]),
            {"error": "RecordRefusedError", "match": "record 1 of 1 .*slot 0.*code 2"},
            faults={"nak_block": {"2": 2}},
        )
    )

    t = Transcript()
    t.identify()
    t.slot(0)
    t.rec(0, ack=1)
    t.rec(0)
    t.end()
    vs.append(
        vector(
            "nak_once",
            "The first record is refused once with code 1; the resend is accepted.",
            t,
            upload_call(0, [0]),
            {"ok": True},
            faults={"nak": {"0": 1}},
            eeprom=blocks(0, [0]),
        )
    )

    # The stamp stops answering (power lost) during the second record.
    t = Transcript()
    t.identify()
    t.slot(0)
    t.rec(0)
    dead_at = t.rx
    t.say(record(1), b"", "record block 1: nothing comes back")
    for _ in range(3):
        t.reset()
        t.say(bytes([X]), b"", "identify: no echo")
    vs.append(
        vector(
            "stops_answering",
            "Power is lost at the second record: no echo; three reconnect attempts fail and "
            "the host reports a timeout naming the record.",
            t,
            upload_call(0, [0, 1]),
            {"error": "FlashTimeoutError", "match": "stopped answering at record 2 of 2"},
            faults={"dead_at_rx": dead_at},
        )
    )

    # Brown-out in the middle of a record: the stamp restarts and runs slot 0; the hardware
    # echo goes on but the byte at the brown-out is lost and no ack comes.
    t = Transcript()
    t.identify()
    t.slot(0)
    brown_at = t.rx + 4
    r0 = record(0)
    t.say(r0, r0[:4] + r0[5:], "record block 0, brown-out at byte 4: 17 echo bytes, no ack")
    t.identify()
    t.slot(0)
    t.rec(0)
    t.end()
    vs.append(
        vector(
            "brownout_resume",
            "A brown-out resets the stamp during the first record; the host resumes.",
            t,
            upload_call(0, [0]),
            {"ok": True},
            faults={"brownout_at_rx": brown_at},
            eeprom=blocks(0, [0]),
        )
    )

    t = Transcript()
    for _ in range(3):
        t.reset()
        t.say(bytes([X]), b"", "identify: no echo")
    vs.append(
        vector(
            "no_echo",
            "No power: nothing comes back on any attempt.",
            t,
            {"op": "connect"},
            {"error": "NoEchoError", "match": "nothing echoed"},
            faults={"dead_at_rx": 0},
        )
    )

    def probes(t: Transcript, answers: dict[str, int]) -> None:
        for challenge in (b"B", b"e", b"P", b"I"):
            t.reset()
            a = answers.get(challenge.decode())
            t.say(challenge, challenge + (bytes([a]) if a is not None else b""), "probe")
            if a is not None:
                return

    t = Transcript()
    for _ in range(3):
        t.identify(answer=None)
    probes(t, {"P": 0x50})
    vs.append(
        vector(
            "wrong_model",
            "A BS2p40 echoes 'X' but does not answer; the probes find it answers 'P' with $50.",
            t,
            {"op": "connect"},
            {"error": "WrongStampError", "match": "BS2p40 v1.0, not a BS2sx"},
            model="BS2p40",
            version=0x50,
        )
    )

    t = Transcript()
    for _ in range(3):
        t.identify(answer=None)
    probes(t, {})
    vs.append(
        vector(
            "not_in_programming_mode",
            "Echo on every byte but no model answers: the stamp is not in programming mode.",
            t,
            {"op": "connect"},
            {"error": "NoReplyError", "match": "not in programming mode"},
            faults={"hang_at_rx": 0},
        )
    )
    return vs


def render() -> str:
    doc = {
        "format": "bstool.protocol-vectors/1",
        "spec": "protocol/programming.md",
        "vectors": build(),
    }
    return json.dumps(doc, indent=1) + "\n"


if __name__ == "__main__":
    OUT.write_text(render(), encoding="utf-8")
    print(f"wrote {OUT}")
