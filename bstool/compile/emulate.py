"""Run compiled module plans at the state level: what the programs compute, without timing.

Each transition every live module exchanges S^t (CA) or relays t+1 states down the leg (NN;
the bypass wire j-1 -> j+1 while j is dead) exactly as the templates do, looking up its next
state in the compiled tables (the packed rule slots, the NN sum tables). A dead module never
answers, so its neighbours keep their last known state of it — R^0, the compiled-in value. The
tests compare this with the reference ``controller.states(T, failed)``; the twin engineer can
compare the BS2sx twin with it too. ``die`` modules run up to S^T and are dead from then on
(their neighbours keep S^T, an NN bypass runs from the next transition on), as the programs
behave once their neighbours have given up on them (protocol/link.md §5).
"""

from __future__ import annotations

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
) -> npt.NDArray[np.int64]:
    """States (T+1, n, m) that the compiled robot shows; ``dead`` modules never run, ``die``
    modules stop after showing S^T."""
    by_id = {p.mid: p for p in plans}
    n = max(p.mid.leg for p in plans) + 1
    m = max(p.mid.module for p in plans) + 1
    from_start = set(dead)
    state = {p.mid: p.r0 for p in plans}
    known = {p.mid: [s for _, s in p.known] for p in plans}
    frames = [_grid(state, n, m)]
    family = plans[0].family
    for t in range(transitions):
        # stopped: shows S^t for good; a CA module still exchanged S^t before it stopped
        dead_set = from_start | {mid for mid, when in (die or {}).items() if when <= t}
        if family == "ca":
            silent = from_start | {mid for mid, when in (die or {}).items() if when < t}
            for p in plans:
                if p.mid in dead_set:
                    continue
                for i, (peer, _) in enumerate(p.known):
                    if peer not in silent:
                        known[p.mid][i] = state[peer]
            nxt = dict(state)
            for p in plans:
                if p.mid in dead_set:
                    continue
                left = _value(p.left, state[p.mid], known[p.mid])
                right = _value(p.right, state[p.mid], known[p.mid])
                nxt[p.mid] = tables.rule_lookup(p.rule_slots, left, state[p.mid], right)
            state = nxt
        else:
            for leg in range(n):
                for j in range(m):
                    p = by_id[ModuleId(leg, j)]
                    if p.mid in dead_set:
                        continue
                    if p.nn_lead:
                        state[p.mid] = (state[p.mid] + 1) % 16
                        continue
                    upstream = ModuleId(leg, j - 1)
                    if upstream not in dead_set:  # the relayed frame: its knowledge + its state
                        known[p.mid] = [*known[upstream], state[upstream]]
                    elif j >= 2 and ModuleId(leg, j - 2) not in dead_set:  # the bypass wire
                        before = ModuleId(leg, j - 2)
                        known[p.mid][: j - 1] = [*known[before], state[before]]
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
