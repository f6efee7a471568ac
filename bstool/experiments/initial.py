"""§4: how much of its distance a controller keeps when its initial states change slightly.

The paper says CA rules are "tightly coupled with the initial state of the lattice": change
the initial phase angles a little and the motion becomes incoherent, which the NN model was
meant to fix. Here k of the n·m initial states (R^0) change by ±1 and the robot runs as the
controller then goes on; the distance kept is d / d_healthy × 100 % (like M_D, eq. 15).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.experiments.mobility import Evaluate, mobility
from bstool.moduleid import ModuleId, all_modules


@dataclass(frozen=True)
class Nudge:
    """The initial states changed: (module, +1 or -1) each."""

    changes: tuple[tuple[ModuleId, int], ...]

    def to_json(self) -> list[list[object]]:
        return [[str(m), d] for m, d in self.changes]


def draw_nudge(controller: Controller, k: int, rng: np.random.Generator) -> Nudge:
    """k distinct modules, each moved one state up or down (uniform; at 0 or k−1 the only
    way that stays a state)."""
    modules = all_modules(controller.legs, controller.modules)
    if not 1 <= k <= len(modules):
        raise InputError(f"initial-states k must be between 1 and {len(modules)}, got {k}")
    picked = sorted(int(i) for i in rng.choice(len(modules), size=k, replace=False))
    signs = rng.integers(0, 2, size=k) * 2 - 1
    changes = []
    for i, sign in zip(picked, signs, strict=True):
        mid = modules[i]
        s = int(controller.initial_states[mid.leg, mid.module])
        d = int(sign)
        if not 0 <= s + d < controller.k:
            d = -d
        changes.append((mid, d))
    return Nudge(tuple(changes))


def nudged_states(controller: Controller, nudge: Nudge, transitions: int) -> np.ndarray:
    """The state sequence when the robot starts from R^0 changed by ``nudge``.

    R^0 is the start pose for every model. A CA controller then follows its rule from the
    changed lattice; an NN controller reads only its leads' initial states (§4.3), so a
    changed non-lead moves back to where its lead puts it at the first transition.
    """
    init = controller.initial_states.copy()
    for mid, d in nudge.changes:
        init[mid.leg, mid.module] += d
    changed = dataclasses.replace(controller, initial_states=init)
    seq = changed.states(transitions).copy()
    seq[0] = init
    return seq


@dataclass(frozen=True)
class NudgedRun:
    nudge: Nudge
    distance: float
    kept: float  # percent of the healthy distance


def nudged_runs(
    controller: Controller,
    evaluate: Evaluate,
    transitions: int,
    k: int,
    samples: int,
    baseline: float,
    seed: int | Sequence[int] = 0,
) -> list[NudgedRun]:
    """``samples`` random nudges of k initial states (seeded), each run once."""
    rng = np.random.default_rng(seed)
    nudges = [draw_nudge(controller, k, rng) for _ in range(samples)]
    distances = evaluate([nudged_states(controller, n, transitions) for n in nudges])
    return [NudgedRun(n, d, mobility(d, baseline)) for n, d in zip(nudges, distances, strict=True)]
