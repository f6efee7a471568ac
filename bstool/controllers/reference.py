"""Plain per-module reference implementation of the five models, straight from the paper.

One cell at a time, with Python ints and lists, so it reads like equations 4–5, 7–8 and
10–14. It is slow on purpose: the vectorised paths (:mod:`bstool.controllers.ca`,
:mod:`bstool.controllers.nn`) are tested equal to it, and later stages (compiled module
programs, the twin) are checked against it too. Keep it simple.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from bstool.controllers.angles import K, angle_to_state, state_to_angle

Cell = tuple[int, int]
Lattice = list[list[int]]

CA_MODELS = ("ca1d", "ca2dsing", "ca2ddiff")
NN_MODELS = ("nnsig", "nnsin")
MODELS = CA_MODELS + NN_MODELS


def ca_neighbours(model: str, legs: int, modules: int, i: int, j: int) -> tuple[Cell, Cell]:
    """(left, right) neighbour cells of cell (i, j): eq. 4–5 for ca1d, eq. 7–8 for the 2-D CA."""
    n, m = legs, modules
    if model == "ca1d":  # ring lattice per leg, radius 1
        left = (i, j - 1 + m) if j - 1 < 0 else (i, j - 1)  # eq. 4
        right = (i, j + 1 - m) if j + 1 >= m else (i, j + 1)  # eq. 5
        return left, right
    # eq. 8 (L)
    left = ((i - 1, j) if i - 1 >= 0 else (i - 1 + n, j)) if j == 0 else (i, j - 1)
    # eq. 7 (R)
    if j == 0 and i + 1 < n:
        right = (i + 1, j)
    elif j == 0:
        right = (i + 1 - n, j)
    elif j + 1 >= m:
        right = (i, j + 1 - m)
    else:
        right = (i, j + 1)
    return left, right


def rule_index(left: int, self_: int, right: int, k: int = K) -> int:
    """Row of the rule table for a neighbourhood (Table 1's order: 256·L + 16·S + R for k=16)."""
    return k * k * left + k * self_ + right


def ca_step_reference(
    model: str,
    lattice: Lattice,
    rules: Sequence[Sequence[int]],
    frozen: dict[Cell, int],
    views: Mapping[tuple[Cell, Cell], int] | None = None,
) -> Lattice:
    """One synchronous CA transition. ``rules`` is (rule,) or (control rule, leg rule) (eq. 9).

    ``frozen`` maps failed cells to the state they keep; ``views`` maps (reader, neighbour) to
    the state that reader reads for that neighbour (a per-link held state).
    """
    seen = views or {}
    n, m = len(lattice), len(lattice[0])
    nxt = [[0] * m for _ in range(n)]
    for i in range(n):
        for j in range(m):
            if (i, j) in frozen:
                nxt[i][j] = frozen[(i, j)]
                continue
            (li, lj), (ri, rj) = ca_neighbours(model, n, m, i, j)
            rule = rules[0] if (model != "ca2ddiff" or j == 0) else rules[1]
            left = seen.get(((i, j), (li, lj)), lattice[li][lj])
            right = seen.get(((i, j), (ri, rj)), lattice[ri][rj])
            nxt[i][j] = rule[rule_index(left, lattice[i][j], right)]
    return nxt


def activate(activation: str, x: float) -> float:
    """Eq. 13 (``nnsin``: π/3·sin x) or eq. 14 (``nnsig``: 2π/(3(1+e^−x)) − π/3)."""
    if activation == "nnsin":
        return math.pi / 3 * math.sin(x)
    if activation == "nnsig":
        return (2 * math.pi) / (3 * (1 + math.exp(-x))) - math.pi / 3
    raise ValueError(f"unknown activation {activation!r}")


def nn_next_state(
    activation: str, upstream: Sequence[int], weights: Sequence[int], k: int = K
) -> int:
    """Next state of a non-lead module from its upstream modules' t+1 states (eq. 11–14).

    ``upstream[a]`` is S_ia^{t+1} for a = 0..j−1 and ``weights[a]`` is w_aj (0 or 1). The sum
    runs in order a = 0, 1, ... (the vectorised path adds in the same order). The compiler
    precomputes its tables by calling this function.
    """
    x = 0.0
    for s, w in zip(upstream, weights, strict=True):
        x = x + state_to_angle(s, k) * w
    return angle_to_state(activate(activation, x), k)


def nn_leg_from_lead(
    activation: str,
    lead: int,
    weights: Sequence[Sequence[int]],
    frozen: dict[int, int],
    k: int = K,
) -> list[int]:
    """A leg's states when its lead is in state ``lead``: propagate j = 1..m−1 in order.

    ``weights[a][b]`` is w_ab; ``frozen`` maps failed module j to the state it keeps.
    """
    m = len(weights)
    leg = [frozen.get(0, lead)]
    for j in range(1, m):
        if j in frozen:
            leg.append(frozen[j])
        else:
            leg.append(nn_next_state(activation, leg[:j], [weights[a][j] for a in range(j)], k))
    return leg


def nn_initial_reference(
    activation: str, leads: Sequence[int], weights: Sequence[Sequence[Sequence[int]]], k: int = K
) -> Lattice:
    """R^0: each leg propagated from its lead's initial state (no failures)."""
    return [nn_leg_from_lead(activation, s, w, {}, k) for s, w in zip(leads, weights, strict=True)]


def nn_step_reference(
    activation: str,
    lattice: Lattice,
    weights: Sequence[Sequence[Sequence[int]]],
    frozen: dict[Cell, int],
    k: int = K,
) -> Lattice:
    """One NN transition: lead S ← (S+1) mod k (eq. 10), then the leg in order (eq. 11–14)."""
    out = []
    for i, leg in enumerate(lattice):
        fixed = {j: s for (fi, j), s in frozen.items() if fi == i}
        out.append(nn_leg_from_lead(activation, (leg[0] + 1) % k, weights[i], fixed, k))
    return out


def sequence_reference(
    model: str,
    initial: Lattice,
    transitions: int,
    *,
    rules: Sequence[Sequence[int]] = (),
    weights: Sequence[Sequence[Sequence[int]]] = (),
    failed: Sequence[Cell] = (),
    failed_at: Mapping[Cell, int] | None = None,
    rejoin: Mapping[Cell, int] | None = None,
    held: Mapping[Cell, Mapping[Cell, int | tuple[int, int]]] | None = None,
    rejoin_with: Mapping[Cell, int] | None = None,
    k: int = K,
) -> list[Lattice]:
    """R^0..R^T. For NN models ``initial`` only needs the leads; R^0 is propagated.

    ``failed_at[c] = T0``: cell c holds S^T0 in every transition from T0 on; ``rejoin[c] = T2``
    (>= T0): from the transition R^T2 -> R^(T2+1) on it follows its rule again, from the state
    it held. ``failed`` cells fail at 0. CA: ``held[c][N] = T_N`` (<= T0): neighbour N reads
    S_c^(T_N) in every transition from T_N until c rejoins (the others read S_c^T0);
    ``(T_N, T2_N)``: in the transitions T_N <= t < T2_N. ``rejoin_with[c] = T_R`` (< T0 < T2):
    c shows S_c^(T_R) in R^(T0+1)..R^T2 and resumes from it.
    """
    if model in NN_MODELS:
        current = nn_initial_reference(model, [leg[0] for leg in initial], weights, k)
    else:
        current = [list(leg) for leg in initial]
    fail = {**dict(failed_at or {}), **dict.fromkeys(failed, 0)}
    back = dict(rejoin or {})
    spans = {
        (reader, c): span if isinstance(span, tuple) else (span, back.get(c, transitions))
        for c, readers in (held or {}).items()
        for reader, span in readers.items()
    }
    frames = [current]
    for t in range(transitions):
        for (i, j), t_r in (rejoin_with or {}).items():
            if t == fail[i, j] + 1:
                current[i][j] = frames[t_r][i][j]
        frozen = {
            (i, j): current[i][j]
            for (i, j), t0 in fail.items()
            if t0 <= t and back.get((i, j), transitions) > t
        }
        views = {
            (reader, c): frames[tn][c[0]][c[1]]
            for (reader, c), (tn, until) in spans.items()
            if tn <= t < until
        }
        if model in NN_MODELS:
            current = nn_step_reference(model, current, weights, frozen, k)
        else:
            current = ca_step_reference(model, current, rules, frozen, views)
        frames.append(current)
    for (i, j), t_r in (rejoin_with or {}).items():  # a run that ends in R^(T0+1)
        if transitions == fail[i, j] + 1:
            current[i][j] = frames[t_r][i][j]
    return frames
