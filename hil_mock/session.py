"""One twin run: (fleet → flash) → twin → reference → check, for ``bstool twin`` and ``demo``.

:func:`run_twin` takes a loaded build (:func:`bstool.buildfile.load`, which has checked every
slot image against the manifest) and :class:`TwinOptions`, and returns a :class:`TwinReport`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bstool.buildfile import Build
from bstool.controllers import Controller, load_controller
from bstool.errors import DeviceError, InputError
from bstool.moduleid import ModuleId
from bstool.timingfile import TimingModel
from hil_mock.check import TwinCheck, check, reference_simulator
from hil_mock.outage import Outage, cut_reference, nn_cut_failures, outage_reference, outages
from hil_mock.perturb import Perturbation
from hil_mock.robot import CHUNK_STEPS, RobotTwin
from hil_mock.schedule_extract import Recorder, stamp_timed_simulator
from hil_mock.twin_result import TwinResult


@dataclass(frozen=True)
class TwinOptions:
    """How to run the twin. ``controller``: what to compare with (default: the build's
    controller.json; None there too: no reference). ``via_flash``: flash n·m fresh virtual
    stamps through the programming protocol first instead of loading the images directly."""

    transitions: int = 30
    failed: Sequence[ModuleId] = ()
    die: Mapping[ModuleId, int] = field(default_factory=dict)
    limp_failed: bool = False
    cut: Sequence[tuple[ModuleId, ModuleId]] = ()
    cut_at: Mapping[tuple[ModuleId, ModuleId], float] = field(default_factory=dict)  # s
    noise: float = 0.0
    seed: int = 0
    physics: bool = True
    via_flash: bool = False
    fleet_name: str | None = None
    controller: Controller | None = None
    timeout_s: float | None = None
    video: str | Path | None = None
    progress: Callable[[int], object] | None = None  # transitions done (increments)
    perturb: Perturbation | None = None  # issue 12 §1: timing, clocks, power-up, resets
    timing: TimingModel | None = None  # issue 13 §2: the stamps' measured timing model


@dataclass
class TwinReport:
    build: Build
    result: TwinResult
    check: TwinCheck
    reference: np.ndarray | None  # (T+1, n, m) of `bstool states`, None without a controller
    sim_distance: float | None  # `bstool simulate`'s distance for the reference
    flash_status: dict[str, str] | None  # module label -> flashed... (via_flash only)
    flash_seconds: float
    twin_seconds: float  # wall-clock time of the twin run
    perturbations: dict[str, object] = field(default_factory=dict)  # what was drawn (--json)

    @property
    def stamp_distance(self) -> float | None:
        """The stamp-timed simulator's distance (this run's own schedule, replayed)."""
        return self.check.stamp_distance

    @property
    def ok(self) -> bool:
        """No module stalled, and the states equal the reference (when there is one)."""
        if self.check.stalled:
            return False
        return self.reference is None or self.check.states_equal


def build_controller(build: Build) -> Controller | None:
    """The controller the build was compiled from (its controller.json), if it is there."""
    path = build.controller_file
    return load_controller(path) if path.is_file() else None


def run_twin(build: Build, options: TwinOptions) -> TwinReport:
    """Run ``build`` on the twin and compare it with the reference (see the module docstring)."""
    ctrl = options.controller if options.controller is not None else build_controller(build)
    eeproms = None
    fleet = None
    flash_status = None
    t0 = time.perf_counter()
    if options.via_flash:
        from hil_mock.fleet import flash_fleet, make_fleet

        fleet = make_fleet(build.legs, build.modules, name=options.fleet_name)
    try:
        if fleet is not None:
            flash_status = flash_fleet(build.root, fleet)
            bad = {k: v for k, v in flash_status.items() if v != "flashed"}
            if bad:
                raise DeviceError(f"flashing the twins failed: {bad}")
            eeproms = dict(fleet.eeproms)
        flash_seconds = time.perf_counter() - t0
        twin = Recorder(
            build,
            eeproms=eeproms,
            failed=options.failed,
            die=options.die,
            limp_failed=options.limp_failed,
            cut=options.cut,
            cut_at=options.cut_at,
            noise=options.noise,
            seed=options.seed,
            physics=options.physics,
            perturb=options.perturb,
            timing=options.timing,
        )
        t0 = time.perf_counter()
        result = _run(twin, options)
        twin_seconds = time.perf_counter() - t0
    finally:
        if fleet is not None:
            fleet.close()
    outs = outages(twin)
    cut_dies = nn_cut_failures(twin) if ctrl is not None and twin._nn else {}
    reference = _reference(ctrl, options, outs, cut_dies) if ctrl is not None else None
    sim_distance = None
    stamp_path = None
    if reference is not None and options.physics:
        sim_distance = reference_simulator(build).run(reference).distance
        stamp_path = _stamp_timed_path(twin, options.transitions)
    limited: list[ModuleId] = []
    if reference is not None and ctrl is not None:
        reference, limited = _documented_limit(build, ctrl, reference, options)
        _hold_frozen(result, limited, options.transitions)
    report = check(
        build,
        result,
        reference,
        options.transitions,
        sim_distance,
        stamp_path=stamp_path,
        outages=outs,
    )
    report.notes += outage_notes(outs)
    if options.cut and reference is not None:
        report.notes.append(_cut_note(ctrl, options, outs))
    if options.cut_at and reference is not None:
        timed = ", ".join(f"{a.label}-{b.label} at {s:g} s" for (a, b), s in options.cut_at.items())
        how = (
            "its downstream end compared as dying at the last transition it took ("
            + ", ".join(f"--die {m.label}@{t}" for m, t in cut_dies.items())
            + ")"
            if cut_dies
            else "compared with the reference without the cut (none describes it here)"
        )
        report.notes.append(f'cut {timed}: {how}; docs/twin.md "A wire cut in a running robot"')
    if limited:
        report.notes.append(
            "modules after two neighbouring dead NN modules ("
            + ", ".join(m.label for m in limited)
            + ") are compared with the compiled programs' emulation: they cannot hear the modules"
            " before the pair and pace on the states they hold (the documented"
            ' limit, docs/compile.md "Checking exactness")'
        )
    return TwinReport(
        build,
        result,
        report,
        reference,
        sim_distance,
        flash_status,
        flash_seconds,
        twin_seconds,
        perturbations=twin.perturb.report(),
    )


def _reference(
    ctrl: Controller, options: TwinOptions, outs: list[Outage], cut_dies: Mapping[ModuleId, int]
) -> np.ndarray:
    """``bstool states`` with the run's failures and long outages; a CA run whose only fault is
    ``--cut`` is compared with each end reading the other's R^0 (:func:`cut_reference`); an NN
    chain wire cut in a running robot as its downstream end dying (:func:`nn_cut_failures`)."""
    from bstool.controllers import NN_MODELS

    faults = options.failed or options.die or any(o.long for o in outs)
    if options.cut and ctrl.model not in NN_MODELS and not faults:
        return cut_reference(ctrl, options.transitions, list(options.cut))
    die = {**cut_dies, **options.die}
    return outage_reference(ctrl, options.transitions, outs, options.failed, die)


def _cut_note(ctrl: Controller | None, options: TwinOptions, outs: list[Outage]) -> str:
    cuts = ", ".join(f"{a.label}-{b.label}" for a, b in options.cut)
    from bstool.controllers import NN_MODELS

    faults = options.failed or options.die or any(o.long for o in outs)
    if ctrl is not None and ctrl.model not in NN_MODELS and not faults:
        return f"cut {cuts}: compared with each end reading the other's R^0 for ever"
    return f"cut {cuts}: compared with the reference without the cut (none describes it here)"


def outage_notes(outs: list[Outage]) -> list[str]:
    """One line per power-off: the reference its module was compared with, and why."""
    notes = []
    for o in outs:
        back = "still off at the end" if o.booted_s is None else f"back at {o.booted_s:g} s"
        if o.long:
            why = "its neighbours went on without it (longer than their dead-limit)"
        else:
            why = "its neighbours waited for it (shorter than their dead-limit)"
        notes.append(
            f"reset of {o.module.label} at {o.off_s:g} s ({back}): {why}; reference "
            f"{o.reference_text()}"
        )
    return notes


def _stamp_timed_path(twin: Recorder, transitions: int) -> np.ndarray | None:
    """The path of the stamp-timed simulator: the commands this run applied, played again on a
    fresh simulator (``bstool simulate --build``, without a second interpreter run)."""
    try:
        schedule = twin.schedule(transitions)
    except InputError:  # no transition at all: no path
        return None
    return stamp_timed_simulator(twin.build).run_schedule(schedule).path


def _run(twin: RobotTwin, options: TwinOptions) -> TwinResult:
    run = {"progress": options.progress, "timeout_s": options.timeout_s}
    if not options.video:
        return twin.run(options.transitions, **run)  # type: ignore[arg-type]
    from bstool.sim.video import VideoRecorder

    assert twin.sim is not None  # the command refuses --video without physics
    model = twin.sim.model
    with VideoRecorder(model, str(options.video)) as rec:
        every = max(1, round(rec.steps_per_frame(model) / CHUNK_STEPS))
        chunks = [0]

        def on_chunk(t: RobotTwin) -> None:
            chunks[0] += 1
            if chunks[0] % every == 0 and t.sim is not None:
                rec.frame(t.sim.data)

        return twin.run(options.transitions, on_chunk=on_chunk, **run)  # type: ignore[arg-type]


def _hold_frozen(result: TwinResult, frozen: list[ModuleId], transitions: int) -> None:
    """Modules past two dead NN neighbours get no frame and pace on the states they hold (the
    documented limit, protocol/link.md §4.6): a constant state; a record that ends early (a
    run shorter than PaceTicks after the second death) is one that has not stalled."""
    for mid in frozen:
        seq = result.states.get(mid, [])
        if seq:
            result.states[mid] = (seq + seq[-1:] * (transitions + 1 - len(seq)))[: transitions + 1]
    result.stalled = [m for m in result.stalled if m not in frozen]


def after_dead_pairs(legs: int, modules: int, dead: Sequence[ModuleId], nn: bool) -> list[ModuleId]:
    """NN modules that come after two neighbouring dead (or dying) modules on their leg: no
    frame from before the pair reaches them (protocol/link.md §2, docs/compile.md)."""
    if not nn:
        return []
    gone = set(dead)
    out = []
    for i in range(legs):
        first = next(
            (
                j
                for j in range(modules - 1)
                if ModuleId(i, j) in gone and ModuleId(i, j + 1) in gone
            ),
            None,
        )
        if first is not None:
            out += [ModuleId(i, j) for j in range(first + 2, modules) if ModuleId(i, j) not in gone]
    return out


def _documented_limit(
    build: Build, ctrl: Controller, reference: np.ndarray, options: TwinOptions
) -> tuple[np.ndarray, list[ModuleId]]:
    """The reference with the documented limit applied: modules after two neighbouring dead NN
    modules follow ``bstool.compile.emulate.run`` (what the compiled tables give them)."""
    from bstool.compile import emulate
    from bstool.compile.calibration import DEFAULT
    from bstool.compile.plan import build_plans
    from bstool.controllers import NN_MODELS

    dead = [*options.failed, *options.die]
    limited = after_dead_pairs(build.legs, build.modules, dead, ctrl.model in NN_MODELS)
    if not limited:
        return reference, []
    plans = build_plans(ctrl, DEFAULT, build.period, build.manifest.controller.hash8)
    emulated = emulate.run(plans, options.transitions, dead=options.failed, die=options.die)
    out = reference.copy()
    for mid in limited:
        out[:, mid.leg, mid.module] = emulated[: len(out), mid.leg, mid.module]
    return out, limited
