"""Regenerate link_frames.json and link_topology.json (protocol/link.md).

    python protocol/vectors/make_link_vectors.py

Built from the rules of protocol/link.md only (no bstool code), like make_vectors.py: the
frames from §3, the wires, pins, masters and colours from §1 and §2. The vectors are
normative: review the diff; tests/test_compile_link.py checks bstool.wire.link and
bstool.compile.topology against them.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODELS = ("ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin")

# §3 Frames
REQUEST_BASE = 0xA8  # request header: $A8 + (t mod 8)
REPLY_BASE = 0xC8  # reply header: $C8 + (t mod 8)


def state_byte(s: int) -> int:
    """§3: the high nibble is the complement of the low one, the low nibble the state."""
    assert 0 <= s <= 15
    return (15 - s) << 4 | s


def frame(reply: bool, t: int, states: list[int]) -> bytes:
    header = (REPLY_BASE if reply else REQUEST_BASE) + t % 8
    return bytes([header, *(state_byte(s) for s in states)])


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
        (False, 0, [7]),
        (True, 0, [12]),
        (False, 5, [0]),
        (True, 7, [15]),
        (False, 8, [3]),
        (False, 3, [1, 4, 9, 15, 0]),
        (True, 2, []),
        (False, 1, [10]),
    ]
    rejected = [
        ("header of a reply where a request is expected", "request", 0, 1, "C8 87"),
        ("transition number differs (receiver at t=1)", "request", 1, 1, "A8 87"),
        ("check nibble wrong (high nibble must be 15 - low nibble)", "request", 0, 1, "A8 77"),
        ("frame too short (payload missing)", "request", 0, 1, "A8"),
        ("second state fails its check", "request", 3, 2, "AB 87 88"),
    ]
    return {
        "format": "bstool.linkvectors/1",
        "spec": "protocol/link.md",
        "request_base": REQUEST_BASE,
        "reply_base": REPLY_BASE,
        "frames": [
            {
                "kind": "reply" if reply else "request",
                "t": t,
                "states": states,
                "bytes": _hex(frame(reply, t, states)),
            }
            for reply, t, states in cases
        ],
        "rejected": [
            {"why": why, "kind": kind, "t": t, "payload": payload, "bytes": raw}
            for why, kind, t, payload, raw in rejected
        ],
        "exchanges": [
            {
                "description": "Fault-free transition t=4 on the ca1d wire L0.M0 (master, P1) - "
                "L0.M1 (slave, P0); S_00^4 = 9, S_01^4 = 2.",
                "steps": [
                    {
                        "from": "0.0",
                        "to": "0.1",
                        "bytes": _hex(frame(False, 4, [9])),
                        "note": "request: header $A8 + 4, state 9 as $69",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(frame(True, 4, [2])),
                        "note": "reply after the slave's checks, within ReplyWait (4 ms)",
                    },
                ],
                "result": {"0.0 knows 0.1": 2, "0.1 knows 0.0": 9},
            },
            {
                "description": "NN relay at t=6 on the wire L2.M2 (master, P1) - L2.M3 (slave, "
                "P0): the master sends the t+1 states of modules 0..2 = [4, 11, 7]; the slave "
                "stores them in up(0..2) and acknowledges with a bare header.",
                "steps": [
                    {
                        "from": "2.2",
                        "to": "2.3",
                        "bytes": _hex(frame(False, 6, [4, 11, 7])),
                    },
                    {"from": "2.3", "to": "2.2", "bytes": _hex(frame(True, 6, []))},
                ],
            },
            {
                "description": "Lost reply at t=4 on the ca1d wire L0.M0 (master) - L0.M1 "
                "(slave): the reply's header is dropped on the wire, the master retries with the "
                "same request, the slave (still lingering, §4) stores the same state again and "
                "sends the same reply.",
                "steps": [
                    {
                        "from": "0.0",
                        "to": "0.1",
                        "bytes": _hex(frame(False, 4, [9])),
                        "note": "request",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(frame(True, 4, [2])),
                        "note": "reply; the master receives only $D2: not a reply header",
                        "lost": [0],
                    },
                    {
                        "from": "0.0",
                        "to": "0.1",
                        "bytes": _hex(frame(False, 4, [9])),
                        "note": "retry at most ReplyBase + a few statements after $D2",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(frame(True, 4, [2])),
                        "note": "the same reply; then the slave lingers again and hears silence",
                    },
                ],
                "result": {"0.0 knows 0.1": 2, "0.1 knows 0.0": 9},
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
