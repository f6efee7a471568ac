"""The data a module program looks up: CA rule slices per slot, NN next-state tables.

CA: the 4096-entry rule (4 bits each, 2048 bytes = a whole slot) is split by the left
neighbour's state L into :data:`RULE_SLOTS` slots of 1024 bytes; in a slot, entry
256·L + 16·S + R sits at byte (L − base)·128 + 8·S + R div 2, even R in the low nibble.

NN: module j's next state depends on its upstream t+1 states only through the integer sum σ
of the states of modules a < j with w_aj = 1 (eq. 11 is linear in the states), so the table
has 15·|W| + 1 entries, each computed by the reference's own
:func:`bstool.controllers.nn_next_state`.
"""

from __future__ import annotations

from collections.abc import Sequence

from bstool.controllers import Controller, nn_next_state
from bstool.errors import BuildError
from bstool.moduleid import ModuleId

RULE_SLOTS = 2
L_PER_SLOT = 16 // RULE_SLOTS
SLOT_TABLE_BYTES = L_PER_SLOT * 128


def module_rule(ctrl: Controller, mid: ModuleId) -> Sequence[int]:
    """The 4096-entry rule this module applies (eq. 9 for ca2ddiff)."""
    if ctrl.model == "ca2ddiff":
        table = ctrl.control_rule if mid.module == 0 else ctrl.leg_rule
    else:
        table = ctrl.rule
    assert table is not None
    return [int(x) for x in table]


def rule_slot_bytes(rule: Sequence[int], slot: int) -> bytes:
    """The packed slice of ``rule`` held by rule slot ``slot`` (1..RULE_SLOTS)."""
    base = (slot - 1) * L_PER_SLOT
    out = bytearray()
    for left in range(base, base + L_PER_SLOT):
        for me in range(16):
            for right in range(0, 16, 2):
                idx = 256 * left + 16 * me + right
                out.append(rule[idx] | rule[idx + 1] << 4)
    return bytes(out)


def rule_lookup(slots: Sequence[bytes], left: int, me: int, right: int) -> int:
    """What the rule slots' READ code computes (the Python mirror of templates/pbasic)."""
    data = slots[left // L_PER_SLOT]
    byte = data[(left % L_PER_SLOT) * 128 + me * 8 + (right >> 1)]
    return byte >> ((right & 1) * 4) & 15


def nn_weights_in(ctrl: Controller, mid: ModuleId) -> list[int]:
    """w_aj for a = 0..j−1 of module j = mid.module on leg mid.leg."""
    assert ctrl.weights is not None
    return [int(ctrl.weights[mid.leg][a][mid.module]) for a in range(mid.module)]


def _spread(total: int, slots: Sequence[int], size: int, reverse: bool) -> list[int]:
    """Upstream states (length ``size``) with the ``slots`` positions summing to ``total``."""
    ups = [0] * size
    order = list(reversed(slots)) if reverse else list(slots)
    for a in order:
        take = min(15, total)
        ups[a] = take
        total -= take
    return ups


def nn_table(ctrl: Controller, mid: ModuleId) -> list[int]:
    """Next state of non-lead module ``mid`` for each σ = 0..15·|W| (see module doc)."""
    weights = nn_weights_in(ctrl, mid)
    ones = [a for a, w in enumerate(weights) if w]
    table = []
    for total in range(15 * len(ones) + 1):
        first = nn_next_state(
            ctrl.model, _spread(total, ones, len(weights), False), weights, ctrl.k
        )
        last = nn_next_state(ctrl.model, _spread(total, ones, len(weights), True), weights, ctrl.k)
        if first != last:  # pragma: no cover - the reference would not be a function of σ
            raise BuildError(
                f"{mid.label}: the NN reference gives {first} and {last} for the same upstream "
                f"sum {total}; a sum table cannot reproduce it",
                hint="report this: the controllers' nn_next_state must depend on the sum only",
            )
        table.append(first)
    return table
