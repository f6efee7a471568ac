"""Schedule models for evolution: builds of random controllers per (model, period), fitted once.

Evolution cannot compile and run every candidate on the twin, so :func:`schedule_model`
compiles random controllers of the model (fixed seeds) with the build's own templates,
records on the twin without physics when each module's servo starts each transition
(each module's pulse times, the record every twin keeps), and fits
a :class:`bstool.sim.timed.ScheduleModel`: each module's power-up drive instant, the mean
instant of every transition, each module's mean offset from it at every transition (under the
serve loop the modules drift apart over the first transitions, each at its own pace) and the
mean period: over two builds (the default), or one per build for a
:class:`bstool.sim.timed.ScheduleEnsemble` of K builds (``builds=K``). The builds are
compiled at the period, which sets HoldFrames. Applied to any candidate's state sequence a
model gives that candidate's stamp-timed schedule in microseconds. Each build's instants are
cached in memory per (model, period, robot, transitions, seed, timing model, bstool version,
templates hash): a build compiled and run with one ``bstool.timing/1`` file is never reused
for another timing, and the default model and an ensemble share their first builds.
"""

from __future__ import annotations

import functools
import hashlib
import json
import tempfile
from pathlib import Path

import numpy as np

from bstool import buildfile, timingfile
from bstool.compile import templates_dir
from bstool.compile.build import compile_loaded
from bstool.controllers import Controller
from bstool.errors import BuildError, InputError
from bstool.evolve.problem import Problem
from bstool.robot import RobotSpec, state_to_angle
from bstool.robot.robotfile import Robot
from bstool.sim.timed import ScheduleEnsemble, ScheduleModel
from bstool.timingfile import DEFAULT as DEFAULT_TIMING
from bstool.timingfile import TimingModel
from bstool.version import __version__
from hil_mock.robot import RobotTwin
from hil_mock.schedule import CHUNK_STEPS
from hil_mock.twin_result import NS

#: transitions recorded per representative (MAX_TRANS: what evolution runs)
FIT_TRANSITIONS = 30
#: random controllers averaged per model (each costs one compile and one twin run)
REPRESENTATIVES = 2


def random_controller(model: str, seed: int, *, legs: int = 5, modules: int = 6) -> Controller:
    """A controller of ``model`` from random chromosome bits (``seed``)."""
    problem = Problem(model, legs=legs, modules=modules)
    rng = np.random.default_rng([13, seed])
    if model == "ca2ddiff":
        leg = rng.integers(0, 2, problem.length("leg"), dtype=np.uint8)
        control = rng.integers(0, 2, problem.length("control"), dtype=np.uint8)
        return problem.controller("leg", leg, control)
    return problem.controller("main", rng.integers(0, 2, problem.length("main"), dtype=np.uint8))


def templates_hash() -> str:
    """sha256 over the template files (names and bytes): a new protocol is a new key."""
    h = hashlib.sha256()
    root = Path(templates_dir())
    for path in sorted(root.rglob("*")):
        if path.is_file():
            h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def timing_digest(timing: TimingModel | None) -> str:
    """sha256 of a timing model's canonical JSON ("" for the estimate): its part of the key."""
    if timing is None or timing == DEFAULT_TIMING:
        return ""
    text = json.dumps(timingfile.to_json(timing), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def transition_instants(
    build: buildfile.Build, transitions: int, timing: TimingModel | None = None
) -> tuple[np.ndarray, int]:
    """(A, T + 2) seconds: each module's first servo pulse (column 0) and the first pulse of
    each transition 1..T+1, recorded on the twin without physics (its stamps on ``timing``);
    and the reference actuator."""
    twin = RobotTwin(build, physics=False, timing=timing)  # pulse times only: no command log
    twin.run(transitions + 1)
    rows = []
    for mid in twin.order:
        times = twin.records[mid].times_ns[: transitions + 2]
        if len(times) < transitions + 2:
            raise BuildError(
                f"{build.root}: module {mid} stalled on the twin after {len(times) - 1} "
                "transitions, so its schedule cannot be measured",
                hint="run `bstool twin` on a build of this model to see why",
            )
        rows.append(np.array(times, dtype=float) / NS)
    ref = twin.reference
    assert ref is not None
    return np.stack(rows), ref.leg * build.modules + ref.module


def fit(
    instants: list[np.ndarray], reference: int, states: int, timestep: float = 0.002
) -> ScheduleModel:
    """Average the instants of several builds (same model, period and robot); ``timestep``:
    the robot's physics step (the twin's chunk is CHUNK_STEPS of them)."""
    c = np.mean(np.stack(instants), axis=0)  # (A, T + 2)
    base = np.zeros(c.shape[1] - 1)
    base[1:] = c[:, 1:-1].mean(axis=0)
    offset = np.zeros((c.shape[1] - 1, c.shape[0]))  # per transition: the spread grows
    offset[1:] = np.mean([(x[:, 1:-1] - x[:, 1:-1].mean(axis=0)).T for x in instants], 0)
    diffs = np.diff(base[1:])
    period = float(diffs[1:].mean() if len(diffs) > 1 else diffs.mean() if len(diffs) else 0)
    grid = CHUNK_STEPS * timestep  # the twin's chunk at the robot's physics step
    angles = state_to_angle(np.arange(states), states)
    return ScheduleModel(grid, c[:, 0], base, offset, period, reference, np.asarray(angles))


@functools.lru_cache(maxsize=64)
def _instants(
    model: str,
    period: float | None,
    legs: int,
    modules: int,
    transitions: int,
    seed: int,
    key: str,
    timing: TimingModel | None,
    spec: RobotSpec | None = None,
) -> tuple[np.ndarray, int, int]:
    """One representative build's instants (random controller ``seed``), its reference
    actuator and the model's state count; ``spec``: the robot (None: the default)."""
    ctrl = random_controller(model, seed, legs=legs, modules=modules)
    robot = None if spec is None else Robot(spec)
    with tempfile.TemporaryDirectory(prefix="bstool-schedule-") as tmp:
        out = Path(tmp) / f"b{seed}"
        res = compile_loaded(ctrl, out, period=period, timing=timing, robot=robot)
        c, reference = transition_instants(buildfile.Build(out, res.manifest), transitions, timing)
    return c, reference, ctrl.k


def schedule_model(
    model: str,
    *,
    period: float | None = None,
    legs: int = 5,
    modules: int = 6,
    transitions: int = FIT_TRANSITIONS,
    representatives: int = REPRESENTATIVES,
    timing: TimingModel | None = None,
    builds: int = 0,
    spec: RobotSpec | None = None,
) -> ScheduleModel | ScheduleEnsemble:
    """The fitted schedule model of ``model`` at ``period`` (None: compile's default) for
    stamps with ``timing`` (a measured ``bstool.timing/1`` model: the representatives are
    compiled and run with it; None: the estimate); about two seconds per representative
    build the first time, then from the cache.

    ``builds`` = 0: one model, the mean of ``representatives`` builds (how runs before the
    ensemble were evolved: their fitness replays with it); ``builds`` = K >= 1: a
    :class:`ScheduleEnsemble` of K builds each fitted alone (``bstool evolve --stamp-timed``
    since 2026-12-03, ``--schedule-builds``). ``spec``: a robot file's robot (its servo speed
    sets the default period, its timestep the twin's chunk); None or the default robot: the
    default one."""
    if isinstance(builds, bool) or not isinstance(builds, int) or builds < 0:
        raise InputError(f"builds must be a whole number >= 0, got {builds!r}")
    if spec is not None and spec == RobotSpec(legs=legs, modules=modules):
        spec = None
    robot_digest = "" if spec is None else Robot(spec).digest()[:16]
    key = f"{__version__}:{templates_hash()}:{timing_digest(timing)}:{robot_digest}"
    if timing is not None and timing == DEFAULT_TIMING:
        timing = None
    count = builds or representatives
    runs = [
        _instants(model, period, legs, modules, transitions, seed, key, timing, spec)
        for seed in range(count)
    ]
    step = 0.002 if spec is None else spec.timestep
    if not builds:
        return fit([c for c, _, _ in runs], runs[0][1], runs[0][2], step)
    return ScheduleEnsemble(tuple(fit([c], ref, k, step) for c, ref, k in runs))
