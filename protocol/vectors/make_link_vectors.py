"""Regenerate link_frames.json and link_topology.json (protocol/link.md).

    python protocol/vectors/make_link_vectors.py

Built from the rules of protocol/link.md only (no bstool code), like make_vectors.py: the
serve loop's frames from §3, the wires, pins, masters and colours from §1 and §2. The vectors are
normative: review the diff; tests/test_compile_link.py checks bstool.wire.link and
bstool.compile.topology against them.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODELS = ("ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin")

# §3 Frames (the serve loop)
HEADERS = {
    "REQ": 0xA8,
    "REP": 0xC8,
    "READY": 0x50,
    "TOOK": 0x98,
    "WAIT": 0x68,
    "BEHIND": 0xE8,
    "WELCOME": 0xD8,
}
JOIN = 0xB8  # JOIN is $B8, $B8
BARE = {"TOOK", "WAIT", "BEHIND"}  # header only (NN: REQ, REP and READY too)
NN_BARE = {"REQ", "REP", "READY"}


def state_byte(s: int, t: int = 0) -> int:
    """§3: the low nibble is the state, the high one its complement XOR the frame's t."""
    assert 0 <= s <= 15
    return ((15 - s) ^ (t % 8)) << 4 | s


def age_byte(age: int, t: int) -> int:
    """§3: a keep-alive's age a (0..63) as the value 192 + a: low nibble a mod 16, high nibble
    (a mod 16) XOR 15 XOR t XOR (12 + a div 16)."""
    assert 0 <= age <= 63
    low = age % 16
    return (low ^ 15 ^ (t % 8) ^ (12 + age // 16)) << 4 | low


def keepalive(kind: str, t: int, age: int) -> bytes:
    return bytes([HEADERS[kind] + t % 8, age_byte(age, t)])


def frame(kind: str, t: int, states: list[int], *, nn: bool) -> bytes:
    """§3: the bytes of a frame. CA WELCOME: six plain-coded fields (got + 2 fresh, nb, nbp,
    state, prev, t); every other payload is coded with the frame's t."""
    if kind == "JOIN":
        return bytes([JOIN, JOIN])
    header = HEADERS[kind] + t % 8
    if kind in BARE or (nn and kind in NN_BARE):
        return bytes([header])
    code = 0 if kind == "WELCOME" and not nn else t
    return bytes([header, *(state_byte(s, code) for s in states)])


def _rotr(x: int) -> int:
    return (x >> 1 | (x & 1) << 3) & 0xF


def fold(data: bytes) -> int:
    """§4.6: a packed frame's check value; f = 0, then per byte f = f ^ rotr(f) ^ hi ^ lo."""
    f = 0
    for b in data:
        f = f ^ _rotr(f) ^ (b >> 4) ^ (b & 0xF)
    return f


def packed(states: list[int], h: int) -> bytes:
    """§4.6 (NN): the states after READY(h), two to a byte, high nibble first; the last byte's
    low nibble is the odd state or 0, its high nibble the one value that makes the frame fold
    to h (found by trying all 16)."""
    pairs = [states[k] << 4 | states[k + 1] for k in range(0, len(states) - 1, 2)]
    odd = states[-1] if len(states) % 2 else 0
    (check,) = [c for c in range(16) if fold(bytes([*pairs, c << 4 | odd])) == h % 8]
    return bytes([*pairs, check << 4 | odd])


def _flips(data: bytes, *bits: int) -> str:
    out = bytearray(data)
    for bit in bits:
        out[bit // 8] ^= 1 << (bit % 8)
    return _hex(bytes(out))


def _hex(data: bytes) -> str:
    return data.hex(" ").upper()


# §1 Pins by the role of the other end
P_PREV, P_NEXT, P_LEFT, P_RIGHT, P_BYPREV, P_BYNEXT = 0, 1, 2, 3, 2, 3

Module = tuple[int, int]  # (leg, module); tuple order is the canonical order of §2


def _pin(model: str, legs: int, modules: int, me: Module, other: Module) -> int:
    """§1: the pin at ``me`` of the wire to ``other``."""
    (i, j), (k, peer) = me, other
    if model.startswith("nn"):
        return {j - 1: P_PREV, j + 1: P_NEXT, j - 2: P_BYPREV, j + 2: P_BYNEXT}[peer]
    if i == k:  # the leg ring
        return P_NEXT if peer == (j + 1) % modules else P_PREV
    return P_RIGHT if k == (i + 1) % legs else P_LEFT  # the ring of leads (2-D CA)


def _wires(model: str, legs: int, modules: int) -> list[tuple[Module, Module]]:
    """§2: the wires per model, each as (master, slave): the master comes first."""
    pairs: set[tuple[Module, Module]] = set()
    for i in range(legs):
        for j in range(modules):
            if model.startswith("nn"):
                if j >= 1:
                    pairs.add(((i, j - 1), (i, j)))  # the chain
                if j >= 2:
                    pairs.add(((i, j - 2), (i, j)))  # the bypass around module j - 1
            else:
                a, b = (i, j), (i, (j + 1) % modules)
                pairs.add((min(a, b), max(a, b)))
    if model in ("ca2dsing", "ca2ddiff"):
        for i in range(legs):
            a, b = (i, 0), ((i + 1) % legs, 0)
            pairs.add((min(a, b), max(a, b)))
    return sorted(pairs)


def _colours(model: str, wires: list[tuple[Module, Module]]) -> dict[tuple[Module, Module], int]:
    """§2: NN chain j-1 -> j has colour j-1, bypass j-1 -> j+1 colour j+1; CA: greedy in
    canonical order, the smallest colour not yet used at either end."""
    out: dict[tuple[Module, Module], int] = {}
    used: dict[Module, set[int]] = {}
    for a, b in wires:
        if model.startswith("nn"):
            colour = a[1] if b[1] == a[1] + 1 else b[1]
        else:
            taken = used.get(a, set()) | used.get(b, set())
            colour = min(c for c in range(len(taken) + 1) if c not in taken)
        out[(a, b)] = colour
        used.setdefault(a, set()).add(colour)
        used.setdefault(b, set()).add(colour)
    return out


def _label(m: Module) -> str:
    return f"{m[0]}.{m[1]}"


def wire_list(model: str, legs: int, modules: int) -> list[dict[str, object]]:
    wires = _wires(model, legs, modules)
    colours = _colours(model, wires)
    nn = model.startswith("nn")
    rows = []
    for (a, b), colour in sorted(colours.items(), key=lambda item: (item[1], item[0])):
        rows.append(
            {
                "master": _label(a),
                "master_pin": _pin(model, legs, modules, a, b),
                "slave": _label(b),
                "slave_pin": _pin(model, legs, modules, b, a),
                "colour": colour,
                # §3 payloads: CA one state each way; NN the master (module j-1) sends the j
                # states S_0..S_{j-1}, the slave a bare header
                "master_sends": a[1] + 1 if nn else 1,
                "slave_sends": 0 if nn else 1,
                "bypass": nn and b[1] == a[1] + 2,
            }
        )
    return rows


def frames() -> dict[str, object]:
    cases = [
        ("ca", "REQ", 0, [7]),
        ("ca", "REP", 0, [12]),
        ("ca", "REQ", 5, [0]),
        ("ca", "REP", 7, [15]),
        ("ca", "REQ", 3, [9]),
        ("ca", "BEHIND", 2, []),
        ("ca", "JOIN", 0, []),
        ("ca", "WELCOME", 4, [3, 9, 8, 2, 1, 4]),
        ("nn", "REQ", 3, []),
        ("nn", "REQ", 6, []),
        ("nn", "READY", 6, []),
        ("nn", "READY", 0, []),
        ("nn", "TOOK", 6, []),
        ("nn", "REP", 6, []),
        ("nn", "WAIT", 1, []),
        ("nn", "JOIN", 0, []),
        ("nn", "WELCOME", 5, [10]),
    ]
    rejected = [
        ("a REP where a REQ's payload check says t = 0 (header t = 1)", "ca", 1, "C9 78"),
        ("the check nibble not XORed with t (t = 1)", "ca", 1, "A9 87"),
        ("check nibble wrong (syndrome 9; A8 77 is a keep-alive of age 55)", "ca", 0, "A8 17"),
        ("frame too short (payload missing)", "ca", 0, "A8"),
        ("an NN REQ with a payload (the states follow READY)", "nn", 3, "AB B7 88"),
        ("READY is not a CA frame", "ca", 6, "56"),
        ("a CA WELCOME whose last field is not its header's t", "ca", 4, "DC C3 69 78 D2 E1 A5"),
        ("a JOIN with one byte lost", "ca", 0, "B8"),
        ("TOOK is not a CA frame", "ca", 2, "9A"),
        *(
            (
                f"a CA REQ(3) payload of syndrome {syn} (neither a state's 0 nor an age's 12-15)",
                "ca",
                3,
                f"AB {((5 ^ 15 ^ 3 ^ syn) << 4 | 5):02X}",
            )
            for syn in range(1, 12)
        ),
        ("an age in an NN frame (NN REPs are bare)", "nn", 2, "CA " + f"{age_byte(5, 2):02X}"),
    ]
    packs = [([1, 4, 9, 15, 0], 3), ([4, 11, 7], 6), ([4, 11], 6), ([9], 0), ([0, 0, 0, 0], 7)]
    states_bad = [  # every single-bit error of one packed frame, and a frame of another h
        {"why": f"packed [1, 4, 9, 15, 0] after READY(3), bit {b} flipped", "family": "nn",
         "h": 3, "states": 5, "bytes": _flips(packed([1, 4, 9, 15, 0], 3), b)}
        for b in range(24)
    ] + [
        {"why": "packed [4, 11, 7] of READY(6) taken after READY(5)", "family": "nn", "h": 5,
         "states": 3, "bytes": _hex(packed([4, 11, 7], 6))},
        {"why": "packed [4, 11, 7] with its last byte lost", "family": "nn", "h": 6,
         "states": 3, "bytes": _hex(packed([4, 11, 7], 6)[:1])},
    ] + [
        {"why": f"packed [1, 4, 9, 15, 0] after READY(3), bit {b} of byte {i} and of byte {j} "
         f"flipped", "family": "nn", "h": 3, "states": 5,
         "bytes": _flips(packed([1, 4, 9, 15, 0], 3), 8 * i + b, 8 * j + b)}
        for i, j in ((0, 1), (0, 2), (1, 2)) for b in range(8)
    ] + [
        {"why": "packed [2, 2] after READY(1) (22 10 with the XOR check of format 3), bit 6 of "
         "byte 0 and bit 2 of byte 1 flipped: the XOR check passed it", "family": "nn", "h": 1,
         "states": 2, "bytes": _flips(packed([2, 2], 1), 6, 10)},
    ]  # fmt: skip
    bad_welcome = frame("WELCOME", 4, [3, 9, 8, 2, 1, 5], nn=False)
    assert bad_welcome.hex(" ").upper() == rejected[6][3]
    return {
        "format": "bstool.linkvectors/5",
        "spec": "protocol/link.md",
        "headers": {**HEADERS, "JOIN": JOIN},
        "frames": [
            {
                "family": family,
                "kind": kind,
                "t": t,
                "states": states,
                "bytes": _hex(frame(kind, t, states, nn=family == "nn")),
            }
            for family, kind, t, states in cases
        ],
        "keepalives": [
            {"kind": kind, "t": t, "age": age, "bytes": _hex(keepalive(kind, t, age))}
            for kind, t, age in (
                ("REQ", 0, 0),
                ("REP", 0, 63),
                ("REQ", 5, 17),
                ("REP", 7, 40),
                ("REQ", 3, 31),
                ("REP", 2, 48),
            )
        ],
        "packed": [
            {"h": h, "states": states, "bytes": _hex(packed(states, h))} for states, h in packs
        ],
        "rejected": [
            *({"why": why, "family": family, "bytes": raw} for why, family, _t, raw in rejected),
            *states_bad,
        ],
        "exchanges": [
            {
                "description": "CA transition t=4 on the ca1d wire L0.M0 (master, P1) - L0.M1 "
                "(slave, P0), S_00^4 = 9, S_01^4 = 2; the first REP is lost, the next round's "
                "REQ(4) is answered again (§4.2).",
                "steps": [
                    {"from": "0.0", "to": "0.1", "bytes": _hex(frame("REQ", 4, [9], nn=False))},
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(frame("REP", 4, [2], nn=False)),
                        "lost": [0],
                    },
                    {"from": "0.0", "to": "0.1", "bytes": _hex(frame("REQ", 4, [9], nn=False))},
                    {"from": "0.1", "to": "0.0", "bytes": _hex(frame("REP", 4, [2], nn=False))},
                ],
                "result": {"0.0 knows 0.1": 2, "0.1 knows 0.0": 9},
            },
            {
                "description": "CA: the slave L0.M1 moved on to t=5 (prev = 2) before its "
                "master got the REP(4): REQ(4) is answered with REP(4) carrying prev (§4.2).",
                "steps": [
                    {"from": "0.0", "to": "0.1", "bytes": _hex(frame("REQ", 4, [9], nn=False))},
                    {"from": "0.1", "to": "0.0", "bytes": _hex(frame("REP", 4, [2], nn=False))},
                ],
                "result": {"0.0 knows 0.1": 2},
            },
            {
                "description": "CA keep-alive at t=4 on the same wire after the exchange: the "
                "master L0.M0 switched about 190 ms before the slave (AgeUnit 17 units of "
                "0.4 ms: its hold clock is at age 40, the slave's at 12); its REQ(4) carries "
                "age 40, the slave keeps the later clock (its own, (40 + 1) x 17 being more) "
                "and answers REP(4) with age 12; "
                "the master sets its clock to (12 + 1) x 17 = 221 units (§4.2).",
                "steps": [
                    {"from": "0.0", "to": "0.1", "bytes": _hex(keepalive("REQ", 4, 40))},
                    {"from": "0.1", "to": "0.0", "bytes": _hex(keepalive("REP", 4, 12))},
                ],
                "result": {"0.0 hold clock": 221, "0.1 age": 12},
            },
            {
                "description": "NN relay at t=6 on the wire L2.M2 (master, P1) - L2.M3 (slave, "
                "P0): the master polls with REQ(6), the slave answers READY(6), the master "
                "sends the t+1 states of modules 0..2 = [4, 11, 7] packed; the slave takes "
                "them (TOOK(6), before its lookup), the master shows S^7, and once the slave "
                "shows it too its answer to the next REQ(6) is REP(6) (§4.6).",
                "steps": [
                    {"from": "2.2", "to": "2.3", "bytes": _hex(frame("REQ", 6, [], nn=True))},
                    {"from": "2.3", "to": "2.2", "bytes": _hex(frame("READY", 6, [], nn=True))},
                    {
                        "from": "2.2",
                        "to": "2.3",
                        "bytes": _hex(packed([4, 11, 7], 6)),
                        "packed": 3,
                        "h": 6,
                    },
                    {"from": "2.3", "to": "2.2", "bytes": _hex(frame("TOOK", 6, [], nn=True))},
                    {"from": "2.2", "to": "2.3", "bytes": _hex(frame("REQ", 6, [], nn=True))},
                    {"from": "2.3", "to": "2.2", "bytes": _hex(frame("REP", 6, [], nn=True))},
                ],
            },
        ],
    }


def topology() -> dict[str, object]:
    return {
        "format": "bstool.linktopology/1",
        "spec": "protocol/link.md",
        "legs": 5,
        "modules": 6,
        "models": {model: wire_list(model, 5, 6) for model in MODELS},
    }


def render() -> dict[str, str]:
    """File name -> the text this script writes."""
    return {
        "link_frames.json": json.dumps(frames(), indent=1) + "\n",
        "link_topology.json": json.dumps(topology(), indent=1) + "\n",
    }


def main() -> None:
    for name, text in render().items():
        (HERE / name).write_text(text)


if __name__ == "__main__":
    main()
