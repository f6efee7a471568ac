"""How far a gait transfers to robots other than the nominal one (``bstool sensitivity``).

Two samples of the robot's uncertain ranges (its robot file's ``[uncertain]`` table, else the
default box; docs/robot.md "Uncertain robot"):

- one parameter at a time: each range at ``points`` values evenly spread over it (in log for a
  log-uniform one), the other parameters nominal;
- jointly: ``samples`` robots drawn from all ranges at once (seeded: every controller meets the
  same robots, so several compare side by side).

The distances come from the evolve evaluators (plain or stamp-timed physics, local threads or a
Dask cluster), so a sensitivity run measures exactly what ``evolve --randomize`` scores.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bstool.experiments import bootstrap
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot

SENSITIVITY_STREAM = 0x53454E53  # "SENS": the joint sample's random stream
DEFAULT_POINTS = 5
DEFAULT_SAMPLES = 32
#: below this many robots the joint sample's intervals are not given (a 10th percentile of
#: fewer than 10 values is its smallest one, and its bootstrap interval says nothing)
MIN_SAMPLES_FOR_INTERVALS = 10

#: evaluate(sequences, robots) -> distances (metres), one per (sequence, robot) pair
Evaluate = Callable[[list[np.ndarray], list[RobotSpec | None]], list[float]]


@dataclass(frozen=True)
class Design:
    """The robots of one sensitivity run: the sweep of each parameter and the joint sample."""

    robot: Robot
    sweeps: dict[str, list[tuple[float, RobotSpec]]]  # parameter -> (value, robot) per point
    joint: list[RobotSpec]
    seed: int

    @property
    def count(self) -> int:
        """Runs per controller: the nominal one, every sweep point and the joint sample."""
        return 1 + sum(len(v) for v in self.sweeps.values()) + len(self.joint)

    def robots(self) -> list[RobotSpec | None]:
        """Every robot in run order: None (the nominal), the sweeps, the joint sample."""
        out: list[RobotSpec | None] = [None]
        for points in self.sweeps.values():
            out += [r for _v, r in points]
        return out + list(self.joint)


def design(robot: Robot, *, points: int = DEFAULT_POINTS, samples: int = DEFAULT_SAMPLES,
           seed: int = 0) -> Design:  # fmt: skip
    """The robots for ``robot``'s uncertain ranges (its box)."""
    import dataclasses

    sweeps: dict[str, list[tuple[float, RobotSpec]]] = {}
    for r in robot.box.ranges:
        values = r.points(robot.spec, points)
        change: list[dict[str, Any]] = [{r.name: v} for v in values]
        sweeps[r.name] = [
            (v, dataclasses.replace(robot.spec, **c)) for v, c in zip(values, change, strict=True)
        ]
    joint = robot.box.samples(robot.spec, samples, seed=[seed, SENSITIVITY_STREAM])
    return Design(robot, sweeps, joint, seed)


@dataclass(frozen=True)
class Transfer:
    """One controller's distances over a :class:`Design` (metres)."""

    name: str
    nominal: float
    sweeps: dict[str, list[tuple[float, float]]]  # parameter -> (value, distance) per point
    joint: list[float]
    extra: dict[str, Any] = field(default_factory=dict)
    # parameter -> Spearman rho of the joint sample's distances with its values (None: constant)
    drivers: dict[str, float | None] = field(default_factory=dict)

    @property
    def mean(self) -> float:
        return float(np.mean(self.joint))

    @property
    def p10(self) -> float:
        return float(np.percentile(self.joint, 10))

    @property
    def worst(self) -> float:
        return float(np.min(self.joint))

    @property
    def worst_tenth(self) -> float:
        """The mean of the worst 10 % of the joint sample (at least one robot)."""
        k = max(1, math.ceil(0.1 * len(self.joint)))
        return float(np.mean(np.sort(self.joint)[:k]))

    @property
    def kept(self) -> float:
        """The joint sample's mean as a fraction of the nominal distance."""
        return self.mean / self.nominal if self.nominal > 0 else 0.0

    def intervals(self) -> dict[str, tuple[float, float]] | None:
        """95 % bootstrap intervals of the joint sample's mean and 10th percentile (metres),
        None below :data:`MIN_SAMPLES_FOR_INTERVALS` robots: how sure those two figures are
        with this many robots (a target such as "p10 at least half the nominal" is met only
        when its whole interval is)."""
        if len(self.joint) < MIN_SAMPLES_FOR_INTERVALS:
            return None
        data = (np.asarray(self.joint, dtype=float),)
        return {
            "mean": bootstrap.interval(data, np.mean),
            "p10": bootstrap.interval(data, _p10),
        }

    def hurts_most(self, name: str) -> tuple[float, float]:
        """(value, distance) of the sweep point of ``name`` with the shortest distance."""
        return min(self.sweeps[name], key=lambda p: p[1])

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "nominal": self.nominal,
            "mean": self.mean,
            "p10": self.p10,
            "worst": self.worst,
            "worst_tenth_mean": self.worst_tenth,
            "kept": self.kept,
            "intervals": _json_intervals(self.intervals()),
            "sweeps": {k: [list(p) for p in v] for k, v in self.sweeps.items()},
            "hurts_most": {
                k: {"value": self.hurts_most(k)[0], "distance": self.hurts_most(k)[1]}
                for k in self.sweeps
            },
            "joint": list(self.joint),
            "drivers": dict(self.drivers),
            **self.extra,
        }


def _p10(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.percentile(x, 10, axis=axis)


def _json_intervals(
    intervals: dict[str, tuple[float, float]] | None,
) -> dict[str, list[float]] | None:
    return None if intervals is None else {k: list(v) for k, v in intervals.items()}


def measure(name: str, states: np.ndarray, plan: Design, evaluate: Evaluate) -> Transfer:
    """Run one controller's ``states`` on every robot of ``plan``."""
    robots = plan.robots()
    distances = evaluate([states] * len(robots), robots)
    it = iter(distances)
    nominal = float(next(it))
    sweeps = {
        key: [(value, float(next(it))) for value, _r in points]
        for key, points in plan.sweeps.items()
    }
    joint = [float(next(it)) for _ in plan.joint]
    return Transfer(name, nominal, sweeps, joint, drivers=drivers(plan, joint))


def drivers(plan: Design, joint: Sequence[float]) -> dict[str, float | None]:
    """Per uncertain parameter, the Spearman rank correlation of the joint sample's distances
    with the parameter's values over the same robots: which parameters the losses go with when
    all vary at once (rho < 0: the larger the value, the shorter the walk). None where either
    side is constant (fewer than 3 robots with a finite distance, or a gait that never moves)."""
    from scipy import stats

    out: dict[str, float | None] = {}
    y = np.asarray(joint, dtype=float)
    finite = np.isfinite(y)
    y = y[finite]
    for key in plan.sweeps:
        x = np.array([float(getattr(r, key)) for r in plan.joint])[finite]
        if len(x) < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
            out[key] = None
            continue
        rho = float(stats.spearmanr(x, y).statistic)
        out[key] = rho if math.isfinite(rho) else None
    return out


def on_batch(
    ev: Any, schedule: Any = None, done: Callable[[int], object] | None = None
) -> Evaluate:
    """A ``BatchEvaluator`` as an :data:`Evaluate`: plain, or stamp-timed on ``schedule`` (a
    schedule model: the first build's schedule of each sequence); ``done(k)`` after each call."""

    def run(seqs: list[np.ndarray], robots: list[RobotSpec | None]) -> list[float]:
        if schedule is None:
            results = ev.evaluate(seqs, robot=robots)
        else:
            from bstool.sim.timed import schedules_of

            results = ev.evaluate_schedules(
                [schedules_of(schedule, s)[0] for s in seqs], robot=robots
            )
        if done is not None:
            done(len(results))
        return [float(r.distance) for r in results]

    return run


def chunked(evaluate: Evaluate, size: int, done: Callable[[int], object] | None) -> Evaluate:
    """``evaluate`` in chunks of ``size`` runs, telling ``done`` after each (progress)."""

    def run(seqs: list[np.ndarray], robots: list[RobotSpec | None]) -> list[float]:
        out: list[float] = []
        for start in range(0, len(seqs), size):
            part = list(evaluate(seqs[start : start + size], robots[start : start + size]))
            out += part
            if done is not None:
                done(len(part))
        return out

    return run


def table(results: Sequence[Transfer], plan: Design) -> str:
    """The printed table: the joint sample's figures, then the harmful end of each range."""
    head = (
        f"{'controller':<24}{'nominal':>9}{'mean':>8}{'p10':>8}{'worst':>8}"
        f"{'worst10%':>10}{'kept':>7}"
    )
    lines = [
        f"joint sample: {len(plan.joint)} robots (seed {plan.seed}); distances in cm after the "
        "run, kept = mean / nominal",
        head,
    ]
    for t in results:
        lines.append(
            f"{t.name[:23]:<24}{t.nominal * 100:9.2f}{t.mean * 100:8.2f}{t.p10 * 100:8.2f}"
            f"{t.worst * 100:8.2f}{t.worst_tenth * 100:10.2f}{t.kept:7.0%}"
        )
    sure = [(t, t.intervals()) for t in results]
    if all(iv is not None for _, iv in sure):
        lines.append("")
        lines.append(
            f"how sure, with {len(plan.joint)} robots: {bootstrap.CONFIDENCE:.0%} bootstrap "
            "intervals (cm; p10 also as a fraction of nominal)"
        )
        for t, iv in sure:
            assert iv is not None
            (m_lo, m_hi), (p_lo, p_hi) = iv["mean"], iv["p10"]
            lines.append(
                f"  {t.name[:23]}: mean {t.mean * 100:.1f} [{m_lo * 100:.1f}, {m_hi * 100:.1f}]; "
                f"p10 {t.p10 * 100:.1f} [{p_lo * 100:.1f}, {p_hi * 100:.1f}]"
                + _of_nominal(t.p10, p_lo, p_hi, t.nominal)
            )
    lines.append("")
    lines.append("one at a time: the value of each parameter that hurts most (distance there, cm)")
    for key in plan.sweeps:
        lo, hi = plan.sweeps[key][0][0], plan.sweeps[key][-1][0]
        cells = []
        for t in results:
            value, dist = t.hurts_most(key)
            cells.append(f"{t.name[:14]}: {value:.4g} ({dist * 100:.1f})")
        lines.append(f"  {key} [{lo:.4g}..{hi:.4g}]: " + "; ".join(cells))
    if len(plan.joint) >= 3:
        lines.append("")
        lines.append(
            "all at once: Spearman rho of the joint sample's distance with each parameter "
            "(rho < 0: larger values walk less; what to measure first on the real robot)"
        )
        for key in plan.sweeps:
            cells = [f"{t.name[:14]}: {_rho(t.drivers.get(key))}" for t in results]
            lines.append(f"  {key}: " + "; ".join(cells))
    return "\n".join(lines)


def _of_nominal(value: float, low: float, high: float, nominal: float) -> str:
    if nominal <= 0:
        return ""
    return f" = {value / nominal:.0%} [{low / nominal:.0%}, {high / nominal:.0%}] of nominal"


def _rho(value: float | None) -> str:
    return "—" if value is None else f"{value:+.2f}"


def plot(results: Sequence[Transfer], plan: Design, path: str) -> None:
    """Distance against each parameter (one curve per controller, the nominal value marked)
    and the joint sample's distribution per controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(plan.sweeps)
    panels = len(keys) + 1
    cols = min(3, panels)
    rows = math.ceil(panels / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    flat = axes.ravel()
    for ax, key in zip(flat, keys, strict=False):
        for t in results:
            xs = [v for v, _d in t.sweeps[key]]
            ax.plot(xs, [d * 100 for _v, d in t.sweeps[key]], marker="o", ms=3, label=t.name)
        ax.axvline(float(getattr(plan.robot.spec, key)), color="0.6", ls=":", lw=1)
        if any(r.name == key and r.distribution == "log-uniform" for r in plan.robot.box.ranges):
            ax.set_xscale("log")
        ax.set_xlabel(key)
        ax.set_ylabel("distance (cm)")
        ax.grid(alpha=0.3)
    ax = flat[len(keys)]
    ax.boxplot([np.array(t.joint) * 100 for t in results], showmeans=True)
    ax.set_xticks(range(1, len(results) + 1), [t.name[:12] for t in results], rotation=20)
    ax.scatter(range(1, len(results) + 1), [t.nominal * 100 for t in results], marker="x",
               color="k", zorder=3, label="nominal")  # fmt: skip
    ax.set_ylabel("distance (cm)")
    ax.set_title(f"joint sample ({len(plan.joint)} robots)", fontsize=9)
    ax.legend(fontsize=7)
    for extra in flat[panels:]:
        extra.axis("off")
    flat[0].legend(fontsize=7)
    fig.suptitle("How far each gait transfers (dotted: the nominal value)")
    fig.tight_layout()
    from bstool import fileio

    with fileio.atomic_open(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
