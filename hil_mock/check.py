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
    mismatched: list[ModuleId]  # modules that showed a state other than the reference's
    first_mismatch: dict[str, Any] | None  # the earliest such state (its module, transition)
    twin_distance: float
    sim_distance: float | None
    # the running period: transitions begun once every module had moved (None: no module
    # made two transitions, nothing to measure)
    period_mean: float | None
    period_std: float | None
    period_nominal: float  # the build's --period (the reference simulation's transition time)
    period_estimate: float  # the manifest's estimated period (timing model)
    servo_gap_max: float
    servo_gap_estimate: float
    stalled: list[ModuleId]
    announcements_ok: bool
    notes: list[str] = field(default_factory=list)
    # the states every compared module showed: R^0..R^(compared - 1) (T + 1 unless one stalled)
    compared: int = 0
    virtual_seconds: float = 0.0  # how long the twin ran (a stall: no state after this)
    # the stamp-timed simulator (the twin's own schedule played by ``bstool simulate``'s
    # physics, ``bstool simulate --build``): its distance and the largest path difference
    stamp_distance: float | None = None
    stamp_path_diff: float | None = None
    # --reset: each power-off, the reference it was compared with (healthy, or failed_at T +
    # rejoin T2 read from the record: hil_mock/outage.py)
    outages: list[dict[str, Any]] = field(default_factory=list)
    # when every running module had made its first transition (s): the start-up, which a
    # neighbour silent from power-up (a cut, a failed module) lengthens by the power-up window
    moving_s: float = math.nan
    # --reset: each reset module's longest time without pulses across its own power-off (s),
    # reported apart from servo_gap_max (the gaps of running modules)
    servo_outages: dict[str, float] = field(default_factory=dict)

    @property
    def verdict(self) -> str:
        """ "equal", "different" (a module showed a state other than the reference's),
        "stalled" (a module stopped short of T without a wrong state), or "unchecked" (no
        reference)."""
        if self.mismatched:
            return "different"
        if self.stalled:
            return "stalled"
        return "equal" if self.states_equal else "unchecked"

    def to_json(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        out["mismatched"] = [str(m) for m in self.mismatched]
        out["stalled"] = [str(m) for m in self.stalled]
        out["verdict"] = self.verdict
        return {k: _finite(v) for k, v in out.items()}


def _finite(value: Any) -> Any:
    """NaN is not JSON: a figure that was not measured is null."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


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
    compared = transitions + 1
    if reference is not None:
        ref = reference[: transitions + 1]
        for mid, seq in compared_states(result.states, ref, outages).items():
            want = ref[:, mid.leg, mid.module].tolist()
            shown = seq[: transitions + 1]
            compared = min(compared, len(shown))
            t = next((i for i, (a, b) in enumerate(zip(shown, want, strict=False)) if a != b),
                     None)  # fmt: skip
            if t is None:  # equal as far as it went (a stalled module is counted as stalled)
                continue
            mismatched.append(mid)
            if first is None or t < first["transition"]:
                first = {"module": str(mid), "transition": t, "twin": shown[t : t + 5],
                         "reference": want[t : t + 5]}  # fmt: skip
    else:
        compared = min([transitions + 1, *(len(s) for s in result.states.values())])
    mean, std = result.running_period_stats()
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
        period_mean=mean if math.isfinite(mean) else None,
        period_std=std if math.isfinite(std) else None,
        period_nominal=build.period,
        period_estimate=max(periods) if periods else math.nan,
        servo_gap_max=max(gaps) if gaps else math.nan,
        servo_gap_estimate=max(estimates) if estimates else math.nan,
        stalled=stalled,
        announcements_ok=ok,
        stamp_distance=_distance(stamp_path),
        stamp_path_diff=_path_diff(stamp_path, result.path),
        outages=[o.to_json() for o in outages],
        compared=compared,
        virtual_seconds=result.virtual_seconds,
        moving_s=result.moving_s,
        servo_outages={str(m): s for m, s in result.servo_outages.items()},
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


def verdict_line(report: TwinCheck, result: TwinResult) -> str:
    """One line saying what the twin's states show against ``bstool states``: equal, how many
    modules differ and from which transition, or how many stalled and where."""
    T, total = report.transitions, len(result.states)
    if report.verdict == "unchecked":
        return "not compared (no controller: give --controller C.json)"
    if report.verdict == "equal":
        within = " (with the notes below)" if report.notes else ""
        return f"EQUAL to `bstool states` for all {total} modules, transitions 0..{T}{within}"
    parts = []
    if report.mismatched and report.first_mismatch is not None:
        parts.append(
            f"DIFFERENT from `bstool states`: {len(report.mismatched)} of {total} modules, "
            f"from transition {report.first_mismatch['transition']}"
        )
    if report.stalled:
        reached = min(len(result.states[m]) for m in report.stalled) - 1
        where = f"past transition {reached}" if reached >= 0 else "at all"
        parts.append(
            f"STALLED: {len(report.stalled)} of {total} modules showed no state {where} "
            f"within {report.virtual_seconds:.2f} s of virtual time"
        )
    shown = report.compared - 1
    span = f"transitions 0..{shown} of {T} compared" if shown >= 0 else "no transition compared"
    return "; ".join(parts) + f" ({span})"
