"""Regenerate link_frames.json and link_topology.json from bstool.compile (protocol/link.md).

    python protocol/vectors/make_link_vectors.py

The vectors are normative: review the diff; tests/test_compile_link.py checks the encoder
against them.
"""

from __future__ import annotations

import json
from pathlib import Path

from bstool.compile.topology import links
from bstool.wire import link

HERE = Path(__file__).resolve().parent
MODELS = ("ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin")


def _hex(data: bytes) -> str:
    return data.hex(" ").upper()


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
        "request_base": link.REQUEST_BASE,
        "reply_base": link.REPLY_BASE,
        "frames": [
            {
                "kind": "reply" if reply else "request",
                "t": t,
                "states": states,
                "bytes": _hex(link.encode_frame(reply, t, states)),
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
                        "bytes": _hex(link.encode_frame(False, 4, [9])),
                        "note": "request: header $A8 + 4, state 9 as $69",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(link.encode_frame(True, 4, [2])),
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
                        "bytes": _hex(link.encode_frame(False, 6, [4, 11, 7])),
                    },
                    {"from": "2.3", "to": "2.2", "bytes": _hex(link.encode_frame(True, 6, []))},
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
                        "bytes": _hex(link.encode_frame(False, 4, [9])),
                        "note": "request",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(link.encode_frame(True, 4, [2])),
                        "note": "reply; the master receives only $D2: not a reply header",
                        "lost": [0],
                    },
                    {
                        "from": "0.0",
                        "to": "0.1",
                        "bytes": _hex(link.encode_frame(False, 4, [9])),
                        "note": "retry at most ReplyBase + a few statements after $D2",
                    },
                    {
                        "from": "0.1",
                        "to": "0.0",
                        "bytes": _hex(link.encode_frame(True, 4, [2])),
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
        "models": {model: [lk.to_json() for lk in links(model, 5, 6)] for model in MODELS},
    }


def main() -> None:
    (HERE / "link_frames.json").write_text(json.dumps(frames(), indent=1) + "\n")
    (HERE / "link_topology.json").write_text(json.dumps(topology(), indent=1) + "\n")


if __name__ == "__main__":
    main()
