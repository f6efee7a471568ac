"""Evaluate many state sequences: one model, one MjData per worker thread, reused across calls.

``mj_step`` releases the GIL, so threads run physics in parallel without copying the model into
other processes. ``mujoco.rollout`` (nthread) is available as ``method="rollout"`` for
comparison; bench/simulator.py measures both and the faster one on this machine is the default
(docs/robot.md, "Batches"). All methods give results bit-identical to :class:`Simulator.run`,
because every run starts from a fully reset MjData (zero warm start).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Any, Literal

import mujoco
import numpy as np

from bstool.cpus import usable_cpus
from bstool.errors import InputError
from bstool.robot import RobotSpec
from bstool.robot.apply import apply_physics, check_applicable
from bstool.sim.simulator import SimResult, Simulator
from bstool.sim.states import validate_states
from bstool.sim.timed import PowerUpCache, StampSchedule, model_copy

Method = Literal["threads", "rollout", "sequential"]
DEFAULT_METHOD: Method = "threads"
# rollout returns the full state at every step; cap one call's output at about this many bytes.
_ROLLOUT_BYTES = 64 * 2**20
#: power-up caches kept for robots other than the nominal one (randomized runs draw new robots
#: every generation: the older ones are dropped first)
_ROBOT_CACHES = 8


def default_workers() -> int:
    """CPUs this process may use (bstool.cpus, the one place worker counts come from)."""
    return usable_cpus()


class BatchEvaluator:
    """Build the model once; evaluate populations again and again.

    >>> with BatchEvaluator(RobotSpec(), workers=2) as ev:   # doctest: +SKIP
    ...     results = ev.evaluate([states_a, states_b])
    """

    def __init__(
        self,
        spec: RobotSpec | None = None,
        workers: int | None = None,
        method: Method = DEFAULT_METHOD,
        transition_time: float | None = None,
        settle_time: float | None = None,
    ) -> None:
        if method not in ("threads", "rollout", "sequential"):
            raise InputError(
                f"unknown batch method {method!r}", hint="use threads, rollout or sequential"
            )
        self.sim = Simulator(spec, transition_time=transition_time, settle_time=settle_time)
        self.spec = self.sim.spec
        self.workers = default_workers() if workers is None else int(workers)
        if self.workers < 1:
            raise InputError(f"workers must be >= 1 (got {workers})")
        self.method: Method = method
        self._datas = [self.sim.data] + [
            mujoco.MjData(self.sim.model) for _ in range(self.workers - 1)
        ]
        self._pool: ThreadPoolExecutor | None = None
        # per worker: a model copy for stamp-timed runs (their gains change while limp) and
        # for other robots' physics, and the robot whose physics it has (None: the nominal)
        self._models: list[mujoco.MjModel] = []
        self._applied: list[RobotSpec | None] = []
        self.power_ups = PowerUpCache()  # stamp-timed runs' power-ups, by their events
        self._robot_power_ups: OrderedDict[RobotSpec, PowerUpCache] = OrderedDict()

    # -- public ----------------------------------------------------------------------------
    def evaluate(
        self,
        states_list: Sequence[Any],
        progress: Callable[[int], None] | None = None,
        *,
        robot: RobotSpec | Sequence[RobotSpec | None] | None = None,
    ) -> list[SimResult]:
        """One :class:`SimResult` per state sequence, in order. ``progress(k)`` is called
        with the number of newly finished evaluations (from worker threads). ``robot``: run
        on another robot's physics (same geometry; :mod:`bstool.robot.apply`), written into
        each worker's model copy when its next job's robot differs; a sequence of robots: one
        per state sequence; None or the evaluator's own robot: the nominal model, untouched."""
        arrays = [
            validate_states(s, self.spec, where=f"states[{i}]") for i, s in enumerate(states_list)
        ]
        if not arrays:
            return []
        robots = self._per_job(robot, len(arrays))
        if robots is not None:
            self._make_worker_models()
            return self._threads_jobs(len(arrays), self._varied_job(arrays, robots), progress)
        if self.method == "sequential" or (self.method == "threads" and self.workers == 1):
            return self._sequential(arrays, progress)
        if self.method == "threads":
            return self._threads(arrays, progress)
        return self._rollout(arrays, progress)

    def evaluate_schedules(
        self,
        schedules: Sequence[StampSchedule],
        progress: Callable[[int], None] | None = None,
        *,
        robot: RobotSpec | Sequence[RobotSpec | None] | None = None,
    ) -> list[SimResult]:
        """Stamp-timed runs (``Simulator.run_schedule``), one per schedule, in order; each
        worker thread has its own model copy (a limp servo changes the model's gains). A
        power-up (``prefix_end``) simulated before is restored from :attr:`power_ups` (one
        cache per robot). ``robot``: as in :meth:`evaluate`."""
        if not schedules:
            return []
        robots = self._per_job(robot, len(schedules)) or [None] * len(schedules)
        caches = {r: self._power_ups(r) for r in dict.fromkeys(robots)}
        self._make_worker_models()

        def job(i: int, w: int) -> SimResult:
            model = self._worker_model(w, robots[i])
            return self.sim.run_schedule(
                schedules[i], self._datas[w], model=model, cache=caches[robots[i]]
            )

        if self.method == "sequential" or self.workers == 1 or len(schedules) == 1:
            out = []
            for i in range(len(schedules)):
                out.append(job(i, 0))
                if progress:
                    progress(1)
            return out
        return self._threads_jobs(len(schedules), job, progress)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> BatchEvaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- robots ----------------------------------------------------------------------------
    def _other(self, robot: RobotSpec | None) -> RobotSpec | None:
        """``robot`` if it is not this evaluator's own (None then); refused if it changes more
        than physics."""
        if robot is None or robot == self.spec:
            return None
        check_applicable(self.spec, robot)
        return robot

    def _per_job(
        self, robot: RobotSpec | Sequence[RobotSpec | None] | None, count: int
    ) -> list[RobotSpec | None] | None:
        """Each job's robot (None: every job runs on the nominal model)."""
        if robot is None or isinstance(robot, RobotSpec):
            one = self._other(robot)
            return None if one is None else [one] * count
        robots = [self._other(r) for r in robot]
        if len(robots) != count:
            raise InputError(f"{len(robots)} robots given for {count} runs: give one per run")
        return None if all(r is None for r in robots) else robots

    def _make_worker_models(self) -> None:
        """The workers' model copies, made once, in the caller's thread before any job runs
        (made lazily by the workers themselves, two threads could each make a list and one
        worker's physics be recorded in the list that was then replaced)."""
        if not self._models:
            self._models = [model_copy(self.sim.model) for _ in self._datas]
            self._applied = [None] * len(self._datas)

    def _worker_model(self, w: int, robot: RobotSpec | None) -> mujoco.MjModel:
        """Worker ``w``'s model copy with ``robot``'s physics (None: the nominal's); only
        worker ``w``'s thread touches entry ``w``."""
        if self._applied[w] != robot:
            apply_physics(
                self._models[w], robot or self.spec, base=self.spec, base_model=self.sim.model
            )
            self._applied[w] = robot
        return self._models[w]

    def _power_ups(self, robot: RobotSpec | None) -> PowerUpCache:
        if robot is None:
            return self.power_ups
        cache = self._robot_power_ups.pop(robot, None) or PowerUpCache()
        self._robot_power_ups[robot] = cache  # the newest last
        while len(self._robot_power_ups) > _ROBOT_CACHES:
            self._robot_power_ups.popitem(last=False)
        return cache

    def _varied_job(
        self, arrays: list[np.ndarray], robots: list[RobotSpec | None]
    ) -> Callable[[int, int], SimResult]:
        def job(i: int, w: int) -> SimResult:
            model = self._worker_model(w, robots[i])
            return self.sim.run_validated(arrays[i], self._datas[w], model=model)

        return job

    # -- methods ---------------------------------------------------------------------------
    def _sequential(
        self, arrays: list[np.ndarray], progress: Callable[[int], None] | None
    ) -> list[SimResult]:
        out = []
        for states in arrays:
            out.append(self.sim.run_validated(states, self._datas[0]))
            if progress:
                progress(1)
        return out

    def _threads(
        self, arrays: list[np.ndarray], progress: Callable[[int], None] | None
    ) -> list[SimResult]:
        def job(i: int, w: int) -> SimResult:
            return self.sim.run_validated(arrays[i], self._datas[w])

        return self._threads_jobs(len(arrays), job, progress)

    def _threads_jobs(
        self,
        count: int,
        job: Callable[[int, int], SimResult],
        progress: Callable[[int], None] | None,
    ) -> list[SimResult]:
        """``job(i, worker)`` for i in 0..count-1 on the worker threads, in order."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="bstool-sim")
        results: list[SimResult | None] = [None] * count
        lock = threading.Lock()
        next_index = [0]
        stop = threading.Event()  # one worker failed (or progress raised): the others stop too

        def worker(w: int) -> None:
            try:
                while not stop.is_set():
                    with lock:
                        i = next_index[0]
                        next_index[0] += 1
                    if i >= count:
                        return
                    results[i] = job(i, w)
                    if progress:
                        progress(1)
            except BaseException:
                stop.set()
                raise

        n = min(self.workers, count)
        futures = [self._pool.submit(worker, w) for w in range(n)]
        wait(futures)  # never return while a worker still uses its MjData
        for f in futures:
            f.result()  # re-raise the first failure
        return [r for r in results if r is not None]

    def _rollout(
        self, arrays: list[np.ndarray], progress: Callable[[int], None] | None
    ) -> list[SimResult]:
        from mujoco import rollout

        sim, model = self.sim, self.sim.model
        out: list[SimResult] = []
        # Group equal lengths: one rollout call needs one nstep.
        by_len: dict[int, list[int]] = {}
        for i, a in enumerate(arrays):
            by_len.setdefault(len(a), []).append(i)
        results: list[SimResult | None] = [None] * len(arrays)
        spec_full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        nstate = mujoco.mj_stateSize(model, spec_full)
        qpos_at = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME)  # time comes first
        data0 = self._datas[0]
        sim.reset(data0)
        init = np.empty(nstate)
        mujoco.mj_getState(model, data0, init, spec_full)
        for frames, idx in by_len.items():
            transitions = frames - 1
            nstep = sim.steps_for(transitions)
            per_run = nstep * (nstate + model.nu) * 8
            chunk = max(1, min(len(idx), _ROLLOUT_BYTES // per_run))
            ends = sim.settle_steps - 1 + sim.steps_per_transition * np.arange(frames)
            reps = np.array([sim.settle_steps] + [sim.steps_per_transition] * transitions)
            for start in range(0, len(idx), chunk):
                part = idx[start : start + chunk]
                control = np.stack([np.repeat(sim.angles(arrays[i]), reps, axis=0) for i in part])
                state, _ = rollout.rollout(
                    model,
                    self._datas,
                    np.tile(init, (len(part), 1)),
                    control,
                    nstep=nstep,
                    initial_warmstart=np.zeros((len(part), model.nv)),
                )
                for k, i in enumerate(part):
                    results[i] = SimResult(state[k, ends, qpos_at : qpos_at + 2].copy())
                if progress:
                    progress(len(part))
        out = [r for r in results if r is not None]
        return out


def evaluate_batch(
    spec: RobotSpec | None,
    states_list: Sequence[Any],
    workers: int | None = None,
    method: Method = DEFAULT_METHOD,
    transition_time: float | None = None,
    settle_time: float | None = None,
) -> list[SimResult]:
    """One-shot convenience; for repeated calls keep a :class:`BatchEvaluator`."""
    with BatchEvaluator(spec, workers, method, transition_time, settle_time) as ev:
        return ev.evaluate(states_list)
