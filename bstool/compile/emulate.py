"""Run compiled module plans at the state level: what the programs compute, without timing.

Each transition every live module serves its wires as the serve loop does (protocol/link.md):
CA modules take the S^t of every neighbour, NN modules relay the t+1 states down the leg (the
bypass wire j-1 -> j+1 while j is dead), each looking up its next state in the compiled
tables (the packed rule slots, the NN sum tables). A dead module never answers: past the
dead-limit its neighbours stop waiting and keep the last state they hold of it (R^0, the
compiled-in value, for one dead from power-up). ``die`` modules run up to S^T and are dead
from then on (their neighbours hold S^T; an NN module relays S^T before it shows it). An NN
module whose upstream wires are all dead (after two dead neighbours, or module 1 after a dead
lead) gets no frame: after PaceTicks it paces, i.e. takes the next state from the upstream
states it holds, as a frame would have brought them (so after a dying pair it shows a constant
state, and module 1 of a dead lead follows the lead's held state), and the rest of its leg
follows it as usual. ``rejoin`` modules
(dead or dying) follow their rule again from the transition T2 on, from the state their
neighbours held for them (``controller.states(..., rejoin=)``, protocol/link.md §4.4).
The tests compare this with the reference ``controller.states(T, failed, failed_at)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from bstool.compile import tables
from bstool.compile.plan import ModulePlan
from bstool.moduleid import ModuleId


def run(
    plans: Sequence[ModulePlan],
    transitions: int,
    dead: Iterable[ModuleId] = (),
    die: Mapping[ModuleId, int] | None = None,
    rejoin: Mapping[ModuleId, int] | None = None,
) -> npt.NDArray[np.int64]:
    """States (T+1, n, m) that the compiled robot shows; ``dead`` modules never run, ``die``
    modules stop after showing S^T, ``rejoin`` modules run again from transition T2."""
    by_id = {p.mid: p for p in plans}
    n = max(p.mid.leg for p in plans) + 1
    m = max(p.mid.module for p in plans) + 1
    fail = {**dict(die or {}), **dict.fromkeys(dead, 0)}
    back = dict(rejoin or {})
    state = {p.mid: p.r0 for p in plans}
    known = {p.mid: [s for _, s in p.known] for p in plans}
    frames = [_grid(state, n, m)]
    family = plans[0].family

    def gone(mid: ModuleId, t: int, *, sent: bool = False) -> bool:
        """Dead in transition t; ``sent``: a module dying at t still sent S^t before."""
        t0 = fail.get(mid, math.inf)
        return (t0 < t if sent else t0 <= t) and t < back.get(mid, math.inf)

    for t in range(transitions):
        if family == "ca":
            for p in plans:
                if gone(p.mid, t):
                    continue
                for i, (peer, _) in enumerate(p.known):
                    if not gone(peer, t, sent=True):
                        known[p.mid][i] = state[peer]
            nxt = dict(state)
            for p in plans:
                if gone(p.mid, t):
                    continue
                left = _value(p.left, state[p.mid], known[p.mid])
                right = _value(p.right, state[p.mid], known[p.mid])
                nxt[p.mid] = tables.rule_lookup(p.rule_slots, left, state[p.mid], right)
            state = nxt
        else:
            for leg in range(n):
                for j in range(m):
                    p = by_id[ModuleId(leg, j)]
                    if gone(p.mid, t):
                        continue
                    if p.nn_lead:
                        state[p.mid] = (state[p.mid] + 1) % 16
                        continue
                    upstream = ModuleId(leg, j - 1)
                    if not gone(upstream, t):  # the relayed frame: its knowledge + its state
                        known[p.mid] = [*known[upstream], state[upstream]]
                    elif j >= 2 and not gone(ModuleId(leg, j - 2), t):  # the bypass wire
                        before = ModuleId(leg, j - 2)
                        known[p.mid][: j - 1] = [*known[before], state[before]]
                    # else no frame reaches it: it paces on the states it holds (PaceTicks)
                    total = sum(known[p.mid][a] for a in p.nn_terms)
                    state[p.mid] = p.nn_table[total]
        frames.append(_grid(state, n, m))
    return np.array(frames, dtype=np.int64)


def _value(expr: str, own: int, known: list[int]) -> int:
    if expr == "state":
        return own
    return known[int(expr[expr.index("(") + 1 : expr.index(")")])]


def _grid(state: dict[ModuleId, int], n: int, m: int) -> list[list[int]]:
    return [[state[ModuleId(i, j)] for j in range(m)] for i in range(n)]
