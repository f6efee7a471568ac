"""Compare what the twin did with what bstool predicts: states with ``bstool states``, the path
with ``bstool simulate``, the timing with the build's manifest estimates."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bstool.buildfile import Build
from bstool.moduleid import ModuleId
from bstool.sim.simulator import Simulator
from bstool.wire import announce
from hil_mock.body import robot_spec
from hil_mock.outage import Outage, compared_states
from hil_mock.twin_result import TwinResult


@dataclass
class TwinCheck:
    transitions: int
    states_equal: bool
    mismatched: list[ModuleId]  # modules whose sequence differs from the reference
    first_mismatch: dict[str, Any] | None
    twin_distance: float
    sim_distance: float | None
    period_mean: float
    period_std: float
    period_nominal: float  # the build's --period (the reference simulation's transition time)
    period_estimate: float  # the manifest's estimated period (timing model)
    servo_gap_max: float
    servo_gap_estimate: float
    stalled: list[ModuleId]
    announcements_ok: bool
    notes: list[str] = field(default_factory=list)
    # the stamp-timed simulator (the twin's own schedule played by ``bstool simulate``'s
    # physics, ``bstool simulate --build``): its distance and the largest path difference
    stamp_distance: float | None = None
    stamp_path_diff: float | None = None
    # --reset: each power-off, the reference it was compared with (healthy, or failed_at T +
    # rejoin T2 read from the record: hil_mock/outage.py)
    outages: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        out["mismatched"] = [str(m) for m in self.mismatched]
        out["stalled"] = [str(m) for m in self.stalled]
        return out


def settle_seconds(build: Build) -> float:
    """How long the twin's robot holds R^0 before the first transition (the join, then R^0
    for a period: the manifest's ``first_transition_s``)."""
    return max(m.timing.first_transition_s for m in build.manifest.modules)


def reference_simulator(build: Build) -> Simulator:
    """``bstool simulate``'s simulator for ``build``'s robot, with the build's transition time
    (``compile --period``), settling in R^0 as long as the twin does before its first
    transition: the twin's path then starts from the same rest pose (a 0.5 s settle leaves the
    robot still sliding, which shifts early paths by cm)."""
    spec = robot_spec(build)
    return Simulator(spec, transition_time=build.period, settle_time=settle_seconds(build))


def check(
    build: Build,
    result: TwinResult,
    reference: np.ndarray | None,
    transitions: int,
    sim_distance: float | None = None,
    *,
    stamp_path: np.ndarray | None = None,
    outages: Sequence[Outage] = (),
) -> TwinCheck:
    """``reference``: the (T+1, n, m) states of ``bstool states`` (with the same failures, and
    ``failed_at`` + ``rejoin`` for the long ``outages``)."""
    mismatched: list[ModuleId] = []
    first = None
    off = {o.module for o in outages if o.long and o.rejoin is None}  # off at the end: dead
    stalled = [m for m in result.stalled if m not in off]
    if reference is not None:
        ref = reference[: transitions + 1]
        for mid, seq in compared_states(result.states, ref, outages).items():
            want = ref[:, mid.leg, mid.module].tolist()
            if seq[: transitions + 1] != want:
                mismatched.append(mid)
                if first is None:
                    t = next(
                        (i for i, (a, b) in enumerate(zip(seq, want, strict=False)) if a != b),
                        len(seq),
                    )
                    first = {"module": str(mid), "transition": t, "twin": seq[t : t + 5],
                             "reference": want[t : t + 5]}  # fmt: skip
    mean, std = result.period_stats()
    hash8 = build.manifest.controller.hash8
    ok = all(line == announce.line(mid, hash8) for mid, line in result.announcements.items())
    estimates = [m.timing.longest_servo_gap_s for m in build.manifest.modules]
    periods = [m.timing.nominal_transition_s for m in build.manifest.modules]
    gaps = list(result.servo_gaps.values())
    return TwinCheck(
        transitions=transitions,
        states_equal=reference is not None and not mismatched and not stalled,
        mismatched=mismatched,
        first_mismatch=first,
        twin_distance=result.distance,
        sim_distance=sim_distance,
        period_mean=mean,
        period_std=std,
        period_nominal=build.period,
        period_estimate=max(periods) if periods else math.nan,
        servo_gap_max=max(gaps) if gaps else math.nan,
        servo_gap_estimate=max(estimates) if estimates else math.nan,
        stalled=stalled,
        announcements_ok=ok,
        stamp_distance=_distance(stamp_path),
        stamp_path_diff=_path_diff(stamp_path, result.path),
        outages=[o.to_json() for o in outages],
    )


def _distance(path: np.ndarray | None) -> float | None:
    if path is None or len(path) < 2:
        return None
    return float(np.hypot(*(path[-1] - path[0])))


def _path_diff(a: np.ndarray | None, b: np.ndarray) -> float | None:
    """The largest distance between matching points of two paths (metres)."""
    if a is None or len(a) == 0 or len(b) == 0:
        return None
    k = min(len(a), len(b))
    return float(np.max(np.linalg.norm(a[:k] - b[:k], axis=1)))
