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
from hil_mock.outage import (
    Outage,
    held_link_reference,
    nn_cut_failures,
    nn_power_up_cut_reference,
    outage_reference,
    outages,
    timed_cut_holds,
)
from hil_mock.perturb import Perturbation
from hil_mock.robot import CHUNK_STEPS, RobotTwin
from hil_mock.schedule_extract import Recorder, stamp_timed_simulator
from hil_mock.stamp.clock import UART_TOLERANCE
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
    # one-way wires: (A, B) -> S: A's bytes to B lost from S seconds (0: from power-up)
    one_way: Mapping[tuple[ModuleId, ModuleId], float] = field(default_factory=dict)
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
            one_way=options.one_way,
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
    links = LinkFaults.of(twin, options)
    reference, cut_notes = _reference(ctrl, options, outs, twin, links) if ctrl else (None, [])
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
    report.notes += links.notes()
    if reference is not None:
        report.notes += cut_notes
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


@dataclass(frozen=True)
class LinkFaults:
    """The run's wire faults as the reference sees them: wires silent from power-up (``--cut
    A-B``, a one-way wire ``A>B``, a wire whose two clocks are further apart than the serial
    link tolerates) and wires gone silent in a running robot (``A-B@S``, ``A>B@S``), each pair
    with S. A one-way wire counts as cut: the link falls back to what a cut does
    (protocol/link.md §4.5, one-way)."""

    power_up: tuple[frozenset[ModuleId], ...]
    timed: dict[frozenset[ModuleId], float]
    one_way: dict[tuple[ModuleId, ModuleId], float]
    clocks: dict[tuple[ModuleId, ModuleId], float]  # (A, B): B's bit time / A's (A's bytes lost)

    @classmethod
    def of(cls, twin: RobotTwin, options: TwinOptions) -> LinkFaults:
        clocks = clock_mismatches(twin)
        power_up = {frozenset(c) for c in options.cut}
        power_up |= {frozenset(ab) for ab, s in options.one_way.items() if s <= 0}
        power_up |= {frozenset(ab) for ab in clocks}
        timed = {frozenset(ab): s for ab, s in options.cut_at.items()}
        timed.update({frozenset(ab): s for ab, s in options.one_way.items() if s > 0})
        for pair in power_up:
            timed.pop(pair, None)
        return cls(tuple(sorted(power_up, key=sorted)), timed, dict(options.one_way), clocks)

    def __bool__(self) -> bool:
        return bool(self.power_up or self.timed)

    def notes(self) -> list[str]:
        out = []
        for (a, b), s in self.one_way.items():
            when = "from power-up" if s <= 0 else f"from {s:g} s"
            out.append(f"one-way wire {a.label}>{b.label} {when}: {a.label}'s bytes to "
                       f"{b.label} are lost, {b.label}'s reach {a.label}; each end falls back "
                       "to what a cut wire does and it is compared as one")  # fmt: skip
        for (a, b), ratio in self.clocks.items():
            out.append(f"wire {a.label}-{b.label}: the two clocks are {abs(ratio - 1) * 100:.2f} % "
                       f"apart ({b.label}'s bit time {ratio:.4f} x {a.label}'s), beyond the "
                       f"serial link's {UART_TOLERANCE * 100:g} % tolerance: {a.label}'s bytes "
                       f"to {b.label} are lost; compared as a one-way wire "
                       f"{a.label}>{b.label} from power-up")  # fmt: skip
        return out


def clock_mismatches(twin: RobotTwin) -> dict[tuple[ModuleId, ModuleId], float]:
    """(A, B) -> B's bit time over A's for every wired pair whose resonators are further apart
    than the UART tolerance in that direction (A's bytes to B are lost: the twin's UART model,
    docs/twin.md "Perturbations")."""
    draws = twin.perturb.draws
    out = {}
    for w in twin.build.manifest.links:
        for a, b in ((w.master, w.slave), (w.slave, w.master)):
            if a in draws and b in draws:
                ratio = draws[b].resonator / draws[a].resonator
                if abs(ratio - 1.0) > UART_TOLERANCE:
                    out[a, b] = ratio
    return out


def _reference(
    ctrl: Controller, options: TwinOptions, outs: list[Outage], twin: RobotTwin, links: LinkFaults
) -> tuple[np.ndarray, list[str]]:
    """``bstool states`` with the run's failures and long outages, and the notes that say how
    the wire faults were compared. Wire faults alone (docs/twin.md "--cut"): CA, each end of a
    wire silent from power-up reads the other's R^0, of one silent from S the last state it got
    (from the record: :func:`hil_mock.outage.timed_cut_holds`); NN, a chain wire silent from
    power-up as ``--fail B`` with B as its upstream failed, one silent from S as B dying at the
    last transition it took (:func:`nn_cut_failures`); a cut bypass changes nothing."""
    from bstool.controllers import NN_MODELS

    faults = options.failed or options.die or any(o.long for o in outs)
    nn = ctrl.model in NN_MODELS
    dies = nn_cut_failures(twin, links.timed) if nn else {}
    if links and not faults:
        if nn:
            ref = nn_power_up_cut_reference(ctrl, options.transitions, links.power_up, dies)
            if ref is not None:
                return ref, _cut_notes(links, nn, dies)
        else:
            holds = [(r, s, 0) for pair in links.power_up for r, s in _ends(pair)]
            holds += timed_cut_holds(twin, links.timed)
            return held_link_reference(ctrl, options.transitions, holds), _cut_notes(
                links, nn, {}, holds
            )
    ref = outage_reference(ctrl, options.transitions, outs, options.failed, {**dies, **options.die})
    none = "compared with the reference without the cut (none describes it here)"
    return ref, [f"{_wires(links)}: {none}"] if links else []


def _ends(pair: frozenset[ModuleId]) -> list[tuple[ModuleId, ModuleId]]:
    a, b = sorted(pair)
    return [(a, b), (b, a)]


def _wires(links: LinkFaults) -> str:
    parts = ["-".join(m.label for m in sorted(p)) for p in links.power_up]
    parts += ["-".join(m.label for m in sorted(p)) + f" at {s:g} s" for p, s in links.timed.items()]
    return "cut " + ", ".join(parts)


def _cut_notes(
    links: LinkFaults,
    nn: bool,
    dies: Mapping[ModuleId, int],
    holds: Sequence[tuple[ModuleId, ModuleId, int]] = (),
) -> list[str]:
    out = []
    if links.power_up:
        wires = ", ".join("-".join(m.label for m in sorted(p)) for p in links.power_up)
        how = ("each cut chain wire's downstream end B as its leg's upstream failed and every "
               "other module as `--fail B` (a cut bypass changes nothing)" if nn
               else "each end reading the other's R^0 for ever")  # fmt: skip
        out.append(f"cut {wires} (silent from power-up): compared with {how}")
    if links.timed:
        wires = ", ".join("-".join(m.label for m in sorted(p)) + f" at {s:g} s"
                          for p, s in links.timed.items())  # fmt: skip
        if nn:
            how = ("its downstream end compared as dying at the last transition it took ("
                   + ", ".join(f"--die {m.label}@{t}" for m, t in dies.items()) + ")"
                   if dies else "a cut bypass changes nothing (the healthy reference)")  # fmt: skip
        else:
            timed = [(r, s, w) for r, s, w in holds if w > 0]
            how = (
                "each end reading the last state it got from the other ("
                + ", ".join(
                    f"{r.label} reads {s.label}'s S^{w - 1} from transition {w}"
                    for r, s, w in timed
                )
                + ", read from the record)"
            )
        out.append(f'cut {wires}: {how}; docs/twin.md "A wire cut in a running robot"')
    return out


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
