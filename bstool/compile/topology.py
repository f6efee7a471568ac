"""Who talks to whom: the neighbours each model reads, the wires (links), their pins and order.

A *link* is one wire between two modules (half duplex, open drain, see protocol/link.md). The
module nearer the start of the canonical order (leg by leg, lead first) is its *master* and
talks first. Links are processed by every module in increasing *colour*: a proper edge
colouring, so a module has at most one link per colour and no cycle of waits can form.

NN links run down each leg: a *chain* wire j−1 → j (colour j−1) and a *bypass* wire j−1 → j+1
(colour j+1) that is used only while the module in between is dead. Module j needs the t+1
states of every upstream module (eq. 11); the bypass keeps them flowing past one dead module.
An NN module runs its wires in the order: receive (chain, then bypass), compute, send (chain,
then bypass); colours only order a module's wires in its serve round.
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.controllers import CA_MODELS, NN_MODELS
from bstool.controllers.reference import ca_neighbours
from bstool.moduleid import ModuleId, all_modules

SERVO_PIN = 12
"""The servo signal pin of every module (PULSOUT)."""

PORTS = {"prev": 0, "next": 1, "lead_left": 2, "lead_right": 3, "bypass_prev": 2, "bypass_next": 3}
"""Link pin by the role of the module at the other end (docs/compile.md, WIRING.md)."""

PORT_TEXT = {
    "prev": "previous module along the leg (towards the disc; the lead's is the leg tip)",
    "next": "next module along the leg (towards the tip; the tip's is the lead)",
    "lead_left": "lead of leg i-1",
    "lead_right": "lead of leg i+1",
    "bypass_prev": "NN: module j-2 (bypass around a dead j-1)",
    "bypass_next": "NN: module j+2 (bypass around a dead j+1)",
}


@dataclass(frozen=True)
class Link:
    """One wire. ``master`` talks first; payloads count state bytes after the header."""

    master: ModuleId
    slave: ModuleId
    colour: int
    master_pin: int
    slave_pin: int
    master_payload: int
    slave_payload: int
    bypass: bool = False  # NN: the wire j-1 -> j+1, used only while module j is dead

    def peer(self, mid: ModuleId) -> ModuleId:
        return self.slave if mid == self.master else self.master

    def pin(self, mid: ModuleId) -> int:
        return self.master_pin if mid == self.master else self.slave_pin

    def to_json(self) -> dict[str, object]:
        """The wire as in protocol/vectors/link_topology.json."""
        return {
            "master": str(self.master),
            "master_pin": self.master_pin,
            "slave": str(self.slave),
            "slave_pin": self.slave_pin,
            "colour": self.colour,
            "master_sends": self.master_payload,
            "slave_sends": self.slave_payload,
            "bypass": self.bypass,
        }


def _role(model: str, legs: int, modules: int, me: ModuleId, other: ModuleId) -> str:
    """The port name at ``me`` for the wire to ``other``."""
    i, j = me
    if model in NN_MODELS:
        if other.module == j - 2:
            return "bypass_prev"
        if other.module == j + 2:
            return "bypass_next"
        return "prev" if other.module < j else "next"
    if other.leg == i:
        if other.module == (j - 1) % modules:
            return "prev"
        return "next"
    if other.leg == (i - 1) % legs:
        return "lead_left"
    return "lead_right"


def reads(model: str, legs: int, modules: int, me: ModuleId) -> tuple[ModuleId, ModuleId]:
    """CA: the (left, right) cells whose state ``me`` needs (eq. 4–5, 7–8)."""
    (li, lj), (ri, rj) = ca_neighbours(model, legs, modules, me.leg, me.module)
    return ModuleId(li, lj), ModuleId(ri, rj)


def links(model: str, legs: int, modules: int) -> list[Link]:
    """Every wire of the robot for ``model``, sorted by (colour, master, slave)."""
    pairs: set[tuple[ModuleId, ModuleId]] = set()
    if model in CA_MODELS:
        for me in all_modules(legs, modules):
            for other in reads(model, legs, modules, me):
                if other != me:
                    pairs.add((min(me, other), max(me, other)))
    elif model in NN_MODELS:
        for i in range(legs):
            for j in range(1, modules):
                pairs.add((ModuleId(i, j - 1), ModuleId(i, j)))
                if j >= 2:
                    pairs.add((ModuleId(i, j - 2), ModuleId(i, j)))
    else:  # pragma: no cover - the loader validates the model
        raise ValueError(model)
    colours: dict[tuple[ModuleId, ModuleId], int] = {}
    used: dict[ModuleId, set[int]] = {}
    for a, b in sorted(pairs):
        if model in NN_MODELS:  # chain j-1 -> j: j-1; bypass j-1 -> j+1: j+1 (round order)
            colour = a.module if b.module == a.module + 1 else b.module
        else:  # greedy: the smallest colour free at both ends
            taken = used.get(a, set()) | used.get(b, set())
            colour = next(c for c in range(len(taken) + 1) if c not in taken)
        colours[(a, b)] = colour
        used.setdefault(a, set()).add(colour)
        used.setdefault(b, set()).add(colour)
    out = []
    for (a, b), colour in colours.items():
        if model in NN_MODELS:
            # upstream sends the t+1 states of modules 0..a; downstream acknowledges (header only)
            pay_a, pay_b = a.module + 1, 0
        else:
            pay_a = pay_b = 1
        out.append(
            Link(
                master=a,
                slave=b,
                colour=colour,
                master_pin=PORTS[_role(model, legs, modules, a, b)],
                slave_pin=PORTS[_role(model, legs, modules, b, a)],
                master_payload=pay_a,
                slave_payload=pay_b,
                bypass=model in NN_MODELS and b.module == a.module + 2,
            )
        )
    return sorted(out, key=lambda lk: (lk.colour, lk.master, lk.slave))


def module_links(all_links: list[Link], mid: ModuleId) -> list[Link]:
    """The links of one module, in the order it runs them: increasing colour (CA); NN: the
    wires from upstream by increasing distance (chain, bypass), then those downstream."""
    mine = [lk for lk in all_links if mid in (lk.master, lk.slave)]
    if any(is_bypass(lk) for lk in all_links):
        mine.sort(key=lambda lk: (lk.master == mid, abs(lk.peer(mid).module - mid.module)))
    return mine


def is_bypass(lk: Link) -> bool:
    """An NN bypass wire j-1 -> j+1 (used only while module j is dead)."""
    return lk.bypass


def pin_role(model: str, legs: int, modules: int, me: ModuleId, other: ModuleId) -> str:
    """Public name of the port at ``me`` that wires to ``other`` (for manifest and WIRING.md)."""
    return _role(model, legs, modules, me, other)
