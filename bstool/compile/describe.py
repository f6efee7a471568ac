"""The build's descriptions: manifest.json (bstool.build/1) and WIRING.md (the harness)."""

from __future__ import annotations

import json
import re
from typing import TYPE_CHECKING, Any

from bstool.compile import link
from bstool.compile.timing import PAD_PIN
from bstool.compile.topology import PORT_TEXT, PORTS, SERVO_PIN, links, pin_role
from bstool.controllers import NN_MODELS, Controller
from bstool.moduleid import ModuleId

if TYPE_CHECKING:
    from bstool.compile.build import ModuleResult

FORMAT = "bstool.build/1"
CONTROLLER_FILE = "controller.json"
"""The compiled controller, copied into the build: `bstool twin BUILD` compares with it."""


_SCALAR_LIST = re.compile(r"\[\s*([^\[\]{}]*?)\s*\]", re.S)


def dumps(obj: Any) -> str:
    """JSON with one field per line but lists of numbers on one line (short, diff-friendly)."""
    text = json.dumps(obj, indent=1)
    return (
        _SCALAR_LIST.sub(lambda mt: "[" + re.sub(r"\s*\n\s*", " ", mt.group(1)) + "]", text) + "\n"
    )


def _flash_slots(res: ModuleResult) -> list[int]:
    """Rule slots first, slot 0 last: slot 0 starts running as soon as it is written."""
    return [*(s.slot for s in reversed(res.slots[1:])), 0]


def manifest(
    ctrl: Controller,
    source: str,
    full_hash: str,
    period: float,
    results: list[ModuleResult],
    tokenized: bool,
) -> dict[str, Any]:
    mods = []
    for res in results:
        p = res.plan
        d = f"modules/{p.dirname}"
        slots = []
        for sr in res.slots:
            entry: dict[str, Any] = {
                "slot": sr.slot,
                "file": f"{d}/{sr.file}",
                "source_sha256": sr.source_sha256,
                "program_bytes": sr.program_bytes,
                "data_bytes": sr.data_bytes,
            }
            if sr.eeprom is not None:
                import hashlib

                entry["eeprom"] = f"{d}/slot{sr.slot}.eeprom"
                entry["packets"] = f"{d}/slot{sr.slot}.packets"
                entry["sha256"] = hashlib.sha256(sr.eeprom).hexdigest()
            slots.append(entry)
        pins: list[dict[str, Any]] = [
            {"pin": SERVO_PIN, "use": "servo"},
            {"pin": PAD_PIN, "use": "pad"},
        ]
        for ll in p.links:
            pins.append(
                {
                    "pin": ll.pin,
                    "use": "link",
                    "port": pin_role(ctrl.model, ctrl.legs, ctrl.modules, p.mid, ll.peer),
                    "neighbour": str(ll.peer),
                    "neighbour_pin": ll.link.pin(ll.peer),
                    "role": "master" if ll.master else "slave",
                    "colour": ll.link.colour,
                    "deadline_ms": ll.deadline,
                    "first_deadline_ms": ll.first_deadline,
                    "miss_iteration_ms": ll.iter_ms,
                    "ok_iteration_ms": ll.ok_ms,
                    **({} if ll.master else {"recover_ms": ll.recover_ms}),
                    **({"bypass": True} if ll.link.bypass else {}),
                    **({"near_deadline_ms": ll.near_deadline} if ll.near_deadline else {}),
                    "send_states": len(ll.send),
                    "receive_states": len(ll.store),
                    "wait_base_units": ll.wait_units,
                }
            )
        mods.append(
            {
                "module": str(p.mid),
                "label": p.label,
                "dir": d,
                "entry": f"{d}/main.bsx",
                "initial_state": p.r0,
                "slots": slots,
                "ram_bytes": res.ram_bytes,
                "ram_bytes_available": 26,
                "pins": pins,
                "servo": {"pulsout": p.pulses, "clipped_states": p.clipped},
                "transition_ms": p.hold_ms,
                "exchange_allowance_ms": p.exch_ms,
                "free_exchange_ms": p.free_ms,
                "hold_step_ms": p.hold_step,
                "hold_pause_ms": p.hold_pause,
                "pad_base": p.pad_base,
                "roll_call_ms": p.roll_ms,
                "timing": res.timing,
                **({"ram_map": res.ram_map} if res.ram_map else {}),
            }
        )
    wires = [
        {
            "master": str(lk.master),
            "master_pin": lk.master_pin,
            "slave": str(lk.slave),
            "slave_pin": lk.slave_pin,
            "colour": lk.colour,
            "bypass": lk.bypass,
        }
        for lk in links(ctrl.model, ctrl.legs, ctrl.modules)
    ]
    order = [
        {"module": str(res.plan.mid), "slots": _flash_slots(res)}
        for res in sorted(results, key=lambda r: r.plan.mid)
    ]
    nn = ctrl.model in NN_MODELS
    return {
        "format": FORMAT,
        "controller": {
            "file": source,
            "copy": CONTROLLER_FILE,
            "hash": full_hash,
            "hash8": full_hash[:8],
            "model": ctrl.model,
        },
        "robot": {"legs": ctrl.legs, "modules": ctrl.modules, "states": ctrl.k},
        "period_s": period,
        "tokenized": tokenized,
        "link": {
            "protocol": "protocol/link.md",
            "baud": link.BAUD,
            "baudmode": link.BAUDMODE,
            "request_base": link.REQUEST_BASE,
            "reply_base": link.REPLY_BASE,
            **({"reply_next_dead_base": link.REPLY_NEXT_DEAD_BASE} if nn else {}),
            "reply_base_units": link.REPLY_BASE_UNITS,
            "recover_units": link.RECOVER_UNITS,
            "linger_units": link.LINGER_UNITS,
            "linger_listens": link.LINGER_LISTENS,
            "silent_transitions": link.SILENT_TRANSITIONS,
        },
        "announcement": "bstool L<leg>.M<module> <hash8>\\r on DEBUG (pin 16, 9600 baud)",
        "modules": mods,
        "links": wires,
        "flash_order": order,
    }


def wiring(
    ctrl: Controller, full_hash: str, results: list[ModuleResult], man: dict[str, Any]
) -> str:
    """WIRING.md: what a person solders, and how to flash and start the robot."""
    roles = {
        pin_role(ctrl.model, ctrl.legs, ctrl.modules, r.plan.mid, ll.peer)
        for r in results
        for ll in r.plan.links
    }
    lines = [
        f"# Wiring for controller {full_hash[:8]} ({ctrl.model}, {ctrl.legs} legs x "
        f"{ctrl.modules} modules)",
        "",
        "Generated by `bstool compile`; the machine-readable version is `manifest.json`",
        "(`links`, and `pins` per module). Protocol: protocol/link.md.",
        "",
        "## Every module",
        "",
        f"- P{SERVO_PIN}: servo signal (Futaba S5301 white/yellow wire); servo + and - to the",
        "  module's supply; all modules share one ground (GND).",
        f"- P{PAD_PIN}: leave unconnected (timing pad: short pulses that make every servo frame",
        "  the same length).",
        "- SIN/SOUT/ATN (programming port): to the flashing adapter only while flashing.",
        "",
        "## Link wires",
        "",
        "One wire per pair of neighbours, used in both directions (half duplex, open drain):",
        "join the two pins below, and add one 10 kΩ pull-up from the wire to +5 V (Vdd of",
        "either module). A 220 Ω series resistor at each pin is recommended. Ports: "
        + "; ".join(f"P{PORTS[k]} = {PORT_TEXT[k]}" for k in PORT_TEXT if k in roles)
        + ".",
        "",
        "| wire | from | pin | to | pin | talks first | colour |",
        "|---|---|---|---|---|---|---|",
    ]
    for number, w in enumerate(man["links"], start=1):
        a, b = (
            ModuleId(*map(int, w["master"].split("."))),
            ModuleId(*map(int, w["slave"].split("."))),
        )
        lines.append(
            f"| {number} | {a.label} | P{w['master_pin']} | {b.label} | P{w['slave_pin']} | "
            f"{a.label} | {w['colour']} |"
        )
    if not man["links"]:
        lines.append("| - | (no links: this model needs none) | | | | | |")
    if "bypass_next" in roles:
        lines += [
            "",
            "NN: the wires P3 (module j-1) to P2 (module j+1) are *bypass* wires: they carry",
            "states only while module j is dead, so that the modules after it still hear every",
            "module before it. Solder them all.",
        ]
    lines += [
        "",
        "## Flashing order",
        "",
        "Flash each module through its programming port, rule slots first and slot 0 last (slot",
        "0 starts running when written). After the last module, switch the whole robot off and",
        "on again so that all modules start together (within about a second) from R^0. Each",
        "module then announces itself on the programming port: `bstool L<leg>.M<module> "
        + full_hash[:8]
        + "`.",
        "The first transition includes the roll call (about "
        + f"{max(r.plan.roll_ms for r in results) / 1000:.1f} s): a module not heard by a"
        " neighbour then is treated as failed (it keeps R^0, like `bstool states --fail`).",
        "",
        "| # | module | slots, in order |",
        "|---|---|---|",
    ]
    for number, entry in enumerate(man["flash_order"], start=1):
        mid = ModuleId(*map(int, entry["module"].split(".")))
        slots = ", ".join(f"{s} (`modules/{mid.label}/slot{s}.packets`)" for s in entry["slots"])
        lines.append(f"| {number} | {mid.label} | {slots} |")
    lines.append("")
    return "\n".join(lines)
