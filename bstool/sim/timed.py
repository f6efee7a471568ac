"""Timed servo commands: the robot moved as its stamps move it, not all 30 servos at once.

A :class:`StampSchedule` lists, per actuator, the instants its servo target changes and the new
angle (NaN: the servo goes limp, no torque, until its next angle), plus the instants at which
the disc position is sampled (the path). :func:`run_schedule` (``Simulator.run_schedule``)
plays it on the MuJoCo robot from a full reset, exactly as the twin drives its actuators: a
limp actuator gets gain and bias 0 and keeps its last control, an angle restores the model's
gain and bias and sets the control. Where the schedule comes from is not this module's
business (docs/twin.md, "Stamp-timed simulation"): ``hil_mock.schedule_extract`` records it
from a build on the twin, and :class:`ScheduleModel` derives it from a state sequence.
"""

from __future__ import annotations

import copy
import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from bstool.errors import InputError

FORMAT = "bstool.stamp-schedule/1"


@dataclass(frozen=True, eq=False)
class StampSchedule:
    """Servo events sorted by time: ``times`` (s), ``actuators`` (leg-major index, lead first),
    ``angles`` (rad, NaN = limp); ``samples``: the path's instants (s), path[0] first."""

    times: np.ndarray
    actuators: np.ndarray
    angles: np.ndarray
    samples: np.ndarray
    actuator_count: int
    prefix_end: float = 0.0
    """Events before this instant are a power-up shared by every schedule with the same ones
    (a :class:`PowerUpCache` key); 0: none. No path sample lies before it."""

    @classmethod
    def from_events(
        cls,
        events: Sequence[tuple[float, int, float]],
        *,
        samples: Sequence[float],
        actuator_count: int,
    ) -> StampSchedule:
        """From (time s, actuator, angle) triples in any order (a stable sort keeps the order
        of events at one instant: the last one wins)."""
        arr = np.array(events, dtype=float).reshape(-1, 3)
        order = np.argsort(arr[:, 0], kind="stable")
        arr = arr[order]
        return cls.checked(
            arr[:, 0], arr[:, 1].astype(np.int64), arr[:, 2], np.asarray(samples, float),
            actuator_count,
        )  # fmt: skip

    @classmethod
    def checked(
        cls,
        times: np.ndarray,
        actuators: np.ndarray,
        angles: np.ndarray,
        samples: np.ndarray,
        actuator_count: int,
    ) -> StampSchedule:
        """Validate the arrays (raising :class:`InputError`) and build the schedule."""
        times = np.ascontiguousarray(times, dtype=float)
        actuators = np.ascontiguousarray(actuators, dtype=np.int64)
        angles = np.ascontiguousarray(angles, dtype=float)
        samples = np.ascontiguousarray(samples, dtype=float)
        if not (times.ndim == actuators.ndim == angles.ndim == 1) or not (
            len(times) == len(actuators) == len(angles)
        ):
            raise InputError("stamp schedule: times, actuators and angles differ in length")
        if len(times) and (
            not np.all(np.isfinite(times)) or times[0] < 0 or np.any(np.diff(times) < 0)
        ):
            raise InputError("stamp schedule: event times must be finite, >= 0 and sorted")
        if len(actuators) and (actuators.min() < 0 or actuators.max() >= actuator_count):
            raise InputError(
                f"stamp schedule: an actuator index is outside 0..{actuator_count - 1}"
            )
        if samples.ndim != 1 or len(samples) < 1 or not np.all(np.isfinite(samples)):
            raise InputError(
                "stamp schedule: needs at least one finite path sample time",
                hint="samples[0] is the instant of path[0]",
            )
        if samples[0] < 0 or np.any(np.diff(samples) < 0):
            raise InputError("stamp schedule: path sample times must be >= 0 and sorted")
        return cls(times, actuators, angles, samples, int(actuator_count))

    @property
    def transitions(self) -> int:
        return len(self.samples) - 1

    @property
    def duration(self) -> float:
        """Seconds of physics a run needs (up to the last path sample)."""
        return float(self.samples[-1])

    def events(self, actuator: int) -> list[tuple[float, float]]:
        """(time, angle) of one actuator, in order (NaN angle = limp)."""
        sel = self.actuators == actuator
        return list(zip(self.times[sel].tolist(), self.angles[sel].tolist(), strict=True))

    def change_times(self, actuator: int) -> np.ndarray:
        """The instants the actuator's angle changes to a new value (limp events left out)."""
        ev = self.events(actuator)
        out, last = [], math.nan
        for t, a in ev:
            if not math.isnan(a) and a != last:
                out.append(t)
                last = a
        return np.array(out)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "actuators": self.actuator_count,
            "samples": self.samples.tolist(),
            "events": [
                [t, int(a), None if math.isnan(x) else x]
                for t, a, x in zip(self.times, self.actuators, self.angles, strict=True)
            ],
        }

    @classmethod
    def from_json(cls, obj: Any, where: str = "stamp schedule") -> StampSchedule:
        try:
            if obj["format"] != FORMAT:
                raise InputError(f"{where}: format is {obj['format']!r}, not {FORMAT}")
            events = [(float(t), int(a), math.nan if x is None else float(x))
                      for t, a, x in obj["events"]]  # fmt: skip
            return cls.from_events(
                events, samples=obj["samples"], actuator_count=int(obj["actuators"])
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(
                f"{where}: not a {FORMAT} object ({exc})",
                hint="write it with StampSchedule.to_json",
            ) from None


class PowerUpCache:
    """The physics state at the end of a schedule's power-up (``prefix_end``), by the power-up's
    events: a candidate whose R^0 an earlier one had starts from there (evolution: offspring
    mostly keep a parent's initial states). Restoring ``mjSTATE_INTEGRATION`` continues the run
    to the bit. For one model; thread-safe; the oldest entries go beyond ``maxsize``."""

    def __init__(self, maxsize: int = 2048) -> None:
        self.maxsize = maxsize
        self.table: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self.hits = self.misses = 0
        self._lock = threading.Lock()

    def get(self, key: bytes) -> tuple[np.ndarray, np.ndarray] | None:
        with self._lock:
            got = self.table.get(key)
            if got is None:
                self.misses += 1
            else:
                self.hits += 1
            return got

    def put(self, key: bytes, state: np.ndarray, limp: np.ndarray) -> None:
        with self._lock:
            self.table[key] = (state, limp)
            while len(self.table) > self.maxsize:
                del self.table[next(iter(self.table))]


_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION


def run_schedule(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    schedule: StampSchedule,
    cache: PowerUpCache | None = None,
) -> np.ndarray:
    """Play ``schedule`` on ``model``/``data`` from a full reset; the (T+1, 2) disc path.

    ``model``'s actuator gains and biases are changed while a servo is limp and restored
    before returning: give each thread its own model (:func:`model_copy`) when running in
    parallel. ``cache``: start from a stored power-up (same physics, fewer steps)."""
    if schedule.actuator_count != model.nu:
        raise InputError(
            f"stamp schedule is for {schedule.actuator_count} servos, the robot has {model.nu}",
            hint="derive the schedule from a build of this robot",
        )
    dt = model.opt.timestep
    ev_steps = np.rint(schedule.times / dt).astype(np.int64)
    smp_steps = np.rint(schedule.samples / dt).astype(np.int64)
    points = np.union1d(ev_steps, smp_steps)
    gain = model.actuator_gainprm.copy()
    bias = model.actuator_biasprm.copy()
    path = np.empty((len(smp_steps), 2))
    acts, angles = schedule.actuators, schedule.angles
    limp = np.zeros(model.nu, dtype=bool)
    mujoco.mj_resetData(model, data)
    now = 0
    e = s = 0
    split, key, stored = -1, b"", None
    if cache is not None and schedule.prefix_end > 0:
        split = int(np.rint(schedule.prefix_end / dt))
        if len(smp_steps) and smp_steps[0] < split:
            split = -1
    if split > 0:
        assert cache is not None
        k = int(np.searchsorted(ev_steps, split))
        key = b"".join((np.int64(split).tobytes(), ev_steps[:k].tobytes(),
                        acts[:k].tobytes(), angles[:k].tobytes()))  # fmt: skip
        stored = cache.get(key)
        points = np.union1d(points, [split])
        if stored is not None:
            state, limp = stored[0], stored[1].copy()
            mujoco.mj_setState(model, data, state, _INTEGRATION)
            model.actuator_gainprm[limp] = 0.0
            model.actuator_biasprm[limp] = 0.0
            now, e = split, k
            points = points[points >= split]
    try:
        for p in points.tolist():
            if p > now:
                mujoco.mj_step(model, data, nstep=p - now)
                now = p
            if p == split and stored is None and cache is not None:  # the power-up's end
                state = np.empty(mujoco.mj_stateSize(model, _INTEGRATION))
                mujoco.mj_getState(model, data, state, _INTEGRATION)
                cache.put(key, state, limp.copy())
            while s < len(smp_steps) and smp_steps[s] == p:
                path[s] = data.qpos[0:2]
                s += 1
            if s == len(smp_steps):
                break
            while e < len(ev_steps) and ev_steps[e] == p:
                a, x = int(acts[e]), float(angles[e])
                if math.isnan(x):
                    model.actuator_gainprm[a] = 0.0
                    model.actuator_biasprm[a] = 0.0
                    limp[a] = True
                else:
                    model.actuator_gainprm[a] = gain[a]
                    model.actuator_biasprm[a] = bias[a]
                    data.ctrl[a] = x
                    limp[a] = False
                e += 1
    finally:
        model.actuator_gainprm[:] = gain
        model.actuator_biasprm[:] = bias
    return path


def model_copy(model: mujoco.MjModel) -> mujoco.MjModel:
    """An independent copy (its own gains), for one worker thread."""
    return copy.deepcopy(model)


@dataclass(frozen=True, eq=False)
class ScheduleModel:
    """When a build of one model, at one period, moves each servo, for any state sequence.

    Fitted from a representative build's recorded schedule (``hil_mock.schedule_model``):
    servo ``a`` is limp from power-up until ``drive[a]`` (s), then holds R^0; its target
    becomes R^t at ``base[t] + offset[a]`` (t = 1..len(base)-1; later transitions follow at
    ``period`` spacing), applied at the start of the ``grid`` chunk holding that instant, as
    the twin does. ``offset`` is (A,) or, per transition, (T_fit + 1, A) (row 0 unused; later
    transitions keep the last row): under the serve loop each module keeps its own pace, so
    the modules' spread grows over the first transitions. The path is sampled when
    ``reference`` starts transition t + 1. What it leaves out: the state-dependent part of the
    offsets (pulse widths shift a module's tries, and under the serve loop its drift from the
    robot's mean: ~0.05 s on average between two controllers' builds, tests/test_stamp_timed.py)
    and the timing changes of failed modules' neighbours."""

    grid: float
    drive: np.ndarray  # (A,) s
    base: np.ndarray  # (T_fit + 1,) s; base[0] unused (0)
    offset: np.ndarray  # (A,) or (T_fit + 1, A) s
    period: float
    reference: int
    angles: np.ndarray  # (k,) rad per state

    @property
    def actuator_count(self) -> int:
        return len(self.drive)

    def instants(self, transitions: int) -> np.ndarray:
        """(T + 2, A) seconds at which each servo starts transitions 0..T+1 (row 0: drive)."""
        fitted = len(self.base) - 1
        t = np.arange(1, transitions + 2)
        last = self.base[fitted]
        base = np.where(
            t <= fitted, self.base[np.minimum(t, fitted)], last + (t - fitted) * self.period
        )
        out = np.empty((transitions + 2, self.actuator_count))
        out[0] = self.drive
        if self.offset.ndim == 2:
            offset = self.offset[np.minimum(t, len(self.offset) - 1)]
        else:
            offset = self.offset[None, :]
        out[1:] = base[:, None] + offset
        return np.floor(out / self.grid + 1e-9) * self.grid

    def schedule(self, states: np.ndarray) -> StampSchedule:
        """The schedule of a (T+1, n, m) state sequence (what its build would do)."""
        seq = np.asarray(states).reshape(len(states), -1)
        if seq.shape[1] != self.actuator_count:
            raise InputError(
                f"states are for {seq.shape[1]} servos, the schedule model for "
                f"{self.actuator_count}"
            )
        T = len(seq) - 1
        when = self.instants(T)
        count = self.actuator_count
        changed = np.ones_like(seq, dtype=bool)
        changed[1:] = seq[1:] != seq[:-1]
        tt, aa = np.nonzero(changed)
        times = np.concatenate([np.zeros(count), when[tt, aa]])
        acts = np.concatenate([np.arange(count), aa])
        angles = np.concatenate([np.full(count, np.nan), self.angles[seq[tt, aa]]])
        order = np.argsort(times, kind="stable")
        samples = when[1:, self.reference]
        first = float(when[1].min())  # no transition starts before: the rest is power-up
        return StampSchedule(times[order], acts[order], angles[order], samples, count, first)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": MODEL_FORMAT,
            "grid": self.grid,
            "drive": self.drive.tolist(),
            "base": self.base.tolist(),
            "offset": self.offset.tolist(),
            "period": self.period,
            "reference": self.reference,
            "angles": self.angles.tolist(),
        }

    @classmethod
    def from_json(cls, obj: Any, where: str = "schedule model") -> ScheduleModel:
        try:
            if obj["format"] != MODEL_FORMAT:
                raise InputError(f"{where}: format is {obj['format']!r}, not {MODEL_FORMAT}")
            return cls(
                float(obj["grid"]),
                np.array(obj["drive"], float),
                np.array(obj["base"], float),
                np.array(obj["offset"], float),
                float(obj["period"]),
                int(obj["reference"]),
                np.array(obj["angles"], float),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: not a {MODEL_FORMAT} object ({exc})") from None


MODEL_FORMAT = "bstool.schedule-model/1"


ENSEMBLE_FORMAT = "bstool.schedule-ensemble/1"


@dataclass(frozen=True, eq=False)
class ScheduleEnsemble:
    """The schedule models of several builds (random controllers of one model and period),
    each fitted alone; a candidate's fitness is its mean distance over all of them.

    Which phase pattern a 2-D CA build's serve loop settles into depends on how its slowest
    wires meet, which no model of the controller predicts (docs/twin.md "For evolution"): the
    shipped ca2dsing walks 28.1–42.7 cm on six builds' patterns. A model averaged over builds
    is a pattern no build has, and evolution overfits it; the mean over builds rewards gaits
    that walk on all of them (fitness 5.0 cm above the twin on average against 8.6), and the
    mean over builds a controller was not scored on predicts a 2-D build to within 5 cm."""

    variants: tuple[ScheduleModel, ...]

    def __post_init__(self) -> None:
        if not self.variants:
            raise InputError("a schedule ensemble needs at least one build's model")

    @property
    def actuator_count(self) -> int:
        return self.variants[0].actuator_count

    def schedules(self, states: np.ndarray) -> list[StampSchedule]:
        """The (T+1, n, m) state sequence on every build's pattern, in order."""
        return [v.schedule(states) for v in self.variants]

    def to_json(self) -> dict[str, Any]:
        return {"format": ENSEMBLE_FORMAT, "variants": [v.to_json() for v in self.variants]}

    @classmethod
    def from_json(cls, obj: Any, where: str = "schedule ensemble") -> ScheduleEnsemble:
        if not isinstance(obj, dict) or obj.get("format") != ENSEMBLE_FORMAT:
            raise InputError(f"{where}: not a {ENSEMBLE_FORMAT} object")
        items = obj.get("variants")
        if not isinstance(items, list):
            raise InputError(f"{where}: 'variants' must be a list")
        return cls(tuple(ScheduleModel.from_json(v, f"{where} variant {i}")
                         for i, v in enumerate(items)))  # fmt: skip


@dataclass(frozen=True, eq=False)
class BuildSchedule:
    """One build's own schedule (its programs' timing on the twin, no model), for the states
    the build was compiled from: ``bstool sensitivity BUILD`` plays the build a user flashes
    on other robots. It plays only those states (a guard: another sequence is an error)."""

    fixed: StampSchedule
    states: np.ndarray

    def schedule(self, states: np.ndarray) -> StampSchedule:
        if not np.array_equal(np.asarray(states), self.states):
            raise InputError(
                "a build's schedule plays only the states it was compiled from",
                hint="give the build's own controller, or its transitions (-T)",
            )
        return self.fixed


ScheduleSource = ScheduleModel | ScheduleEnsemble | BuildSchedule
"""What evolution (or a sensitivity run) plays a candidate's state sequence on."""


def mean_distance(distances: Sequence[float]) -> float:
    """A candidate's stamp-timed fitness from its distances on each schedule (one: itself)."""
    return math.fsum(distances) / len(distances)


def schedules_of(source: ScheduleSource, states: np.ndarray) -> list[StampSchedule]:
    """Every schedule a candidate is scored on: one for a model, one per build of an
    ensemble (its fitness is the mean distance over them)."""
    if isinstance(source, ScheduleEnsemble):
        return source.schedules(states)
    return [source.schedule(states)]
