"""The robot twin: one virtual BS2sx per module, wired as the build says, driving MuJoCo.

Every module runs its own EEPROM image on the token interpreter (:mod:`hil_mock.stamp`). The
twin's jobs live in their own modules, combined here: the servo body (:mod:`hil_mock.body`),
link routing and noise (:mod:`hil_mock.links`), fault injection (:mod:`hil_mock.faults`) and
scheduling (:mod:`hil_mock.schedule`); what it observed is :mod:`hil_mock.twin_result`. The
build is read with :func:`bstool.buildfile.load`. Physics advances in chunks of
:data:`CHUNK_STEPS` MuJoCo steps; the stamps are advanced to the end of each chunk first
(docs/twin.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

import numpy as np

from bstool import buildfile
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.timingfile import TimingModel
from bstool.wire import announce
from hil_mock.body import LIMP_AFTER_S, Body, ServoTrack
from hil_mock.faults import Faults, dying_modules, failed_modules
from hil_mock.links import Links, check_cuts, wires
from hil_mock.perturb import Perturbation, PerturbRun
from hil_mock.schedule import CHUNK_STEPS, Scheduler, advance_globally
from hil_mock.stamp import Stamp, StampIO
from hil_mock.stamp.clock import NOMINAL
from hil_mock.twin_result import (
    NS,
    OFF_STATE,
    ModuleRecord,
    TwinResult,
    ram_reader,
    running_periods,
)

__all__ = [
    "CHUNK_STEPS",
    "LIMP_AFTER_S",
    "NS",
    "ModuleRecord",
    "RobotTwin",
    "ServoTrack",
    "TwinResult",
    "load_build",
]

load_build = buildfile.load
"""Read a build folder (kept under its old name: :func:`bstool.buildfile.load`)."""


class _Eeprom8:
    """Eight slots of bytes (what a module's EEPROM holds after flashing)."""

    def __init__(self, images: Mapping[int, bytes]) -> None:
        self.slots = [bytearray(images.get(n, bytes(2048))) for n in range(8)]

    def read_slot(self, slot: int) -> bytes:
        return bytes(self.slots[slot])

    def write_byte(self, slot: int, addr: int, value: int) -> None:
        self.slots[slot][addr] = value


class _TwinIO(StampIO):
    def __init__(self, twin: RobotTwin, mid: ModuleId) -> None:
        self.twin = twin
        self.mid = mid

    def serial_out(self, stamp: Stamp, pin: int, value: int, start_ns: int, mode: int) -> None:
        if pin < 16:
            self.twin._route(self.mid, pin, value, start_ns, mode)

    def pulse(self, stamp: Stamp, pin: int, start_ns: int, width_ns: int, level: int) -> None:
        servo = self.twin.servos[self.mid]
        if pin == servo.pin:
            self.twin._servo_pulse(self.mid, servo, start_ns, width_ns)


class RobotTwin(Body, Links, Faults, Scheduler):
    """30 virtual modules (or n·m) wired by the build, with the MuJoCo robot as their body.

    ``eeproms`` (module → anything with ``read_slot``/``slot``, e.g. a flashed
    :class:`hil_mock.eeprom.Eeprom`) replaces the build's images, so a robot flashed through the
    programming protocol runs exactly what was flashed. ``failed`` modules never run (silent on
    their links) and their servo holds the R^0 angle (the paper's failed module: a fixed state);
    with ``limp_failed`` it goes limp instead. ``die`` maps modules to the transition T at which
    they die during the run: the stamp stops for good once it has shown S^T on its servo and sent
    S^T to its neighbours (:meth:`_dies_at_pulse`, docs/twin.md); its servo then holds S^T (limp
    with ``limp_failed``). ``cut`` removes links; ``cut_at`` cuts them at a virtual time (s:
    no byte starting then or later crosses); ``one_way`` maps (A, B) to a virtual time (s, 0:
    from power-up) from which A's bytes to B are lost while B's reach A. ``noise`` is the chance
    that a byte on a link is hit (half of the hits drop it, half flip one bit), drawn from
    ``seed``. ``timing``: the stamps' nominal timing model (a measured ``bstool.timing/1``
    file's; default: the estimate), under ``perturb``'s per-module factors.
    """

    def __init__(
        self,
        build: buildfile.Build,
        *,
        eeproms: Mapping[ModuleId, object] | None = None,
        failed: Iterable[ModuleId | str] = (),
        die: Mapping[ModuleId, int] | Mapping[str, int] | None = None,
        limp_failed: bool = False,
        cut: Iterable[tuple[ModuleId, ModuleId]] = (),
        cut_at: Mapping[tuple[ModuleId, ModuleId], float] | None = None,
        one_way: Mapping[tuple[ModuleId, ModuleId], float] | None = None,
        noise: float = 0.0,
        seed: int = 0,
        physics: bool = True,
        perturb: Perturbation | None = None,  # issue 12 §1
        timing: TimingModel | None = None,  # issue 13 §2: a measured timing model
    ) -> None:
        self.build = build
        self.timing = timing
        if not 0.0 <= noise <= 1.0:
            raise InputError(f"link noise must be a probability in 0..1, got {noise}")
        self.noise = noise
        self.noise_events = {"flipped": 0, "dropped": 0}
        self.welcomes = []
        legs, modules = build.legs, build.modules
        self.order = [ModuleId(i, j) for i in range(legs) for j in range(modules)]
        self.noise_rngs = (
            {m: np.random.default_rng([seed, m.leg, m.module]) for m in self.order} if noise else {}
        )
        self.failed = failed_modules(failed, legs, modules)
        self.die = dying_modules(die, self.failed, legs, modules)
        self.limp_failed = limp_failed
        self.died: dict[ModuleId, int] = {}  # module -> virtual ns when its stamp stopped
        self._killed = False
        self._nn = build.manifest.controller.model.startswith("nn")
        cut = list(cut)
        check_cuts(build, [*cut, *(cut_at or {}), *(one_way or {})])
        self.wires = wires(build, cut)
        self.cut_at_ns = {frozenset(ab): round(s * NS) for ab, s in (cut_at or {}).items()}
        self.lost_ns = {(a, b): round(s * NS) for (a, b), s in (one_way or {}).items()}
        self.stamps: dict[ModuleId, Stamp] = {}
        self.records: dict[ModuleId, ModuleRecord] = {m: ModuleRecord() for m in self.order}
        self.servos: dict[ModuleId, ServoTrack] = {}
        self._readers: dict[ModuleId, tuple[Callable[[Stamp], int], Callable[[Stamp], int]]] = {}
        self._init_physics(physics)
        for mid in self.order:
            info = build.module(mid)
            self.servos[mid] = self._servo(mid, info)
            if mid in self.failed:
                r0 = int(info.initial_state)
                self.records[mid].states.append(r0)
                self.servos[mid].limp = limp_failed
                continue
            source = eeproms.get(mid) if eeproms is not None else None
            store = _Eeprom8(build.images(mid)) if source is None else source
            self.stamps[mid] = Stamp(
                store, io=_TwinIO(self, mid), name=mid.label, clock=NOMINAL.with_model(timing)
            )
            ram = info.ram_map
            if not ram or "state" not in ram or "tn" not in ram:
                raise InputError(
                    f"{build.root}: module {mid} has no ram_map in manifest.json",
                    hint="re-run `bstool compile` with this bstool version",
                )
            self._readers[mid] = (ram_reader(ram["state"]), ram_reader(ram["tn"]))
        self.ran: dict[ModuleId, Stamp] = dict(self.stamps)  # every stamp that ever ran
        live = [m for m in self.order if m in self.stamps and m not in self.die]
        self.reference = live[0] if live else next(iter(self.stamps), None)
        self.t_ns = 0
        self.path: list[tuple[float, float]] = []
        self.perturb = PerturbRun.install(self, perturb)  # issue 12 §1: clocks, starts, resets

    def _servo_pulse(self, mid: ModuleId, servo: ServoTrack, start_ns: int, width_ns: int) -> None:
        if mid not in self.stamps:
            return
        if self._dies_at_pulse(mid, self.stamps[mid], after=False):
            self._kill(mid, self.stamps[mid], start_ns)
            return
        if servo.pulses and servo.powered_off:  # across its own power-off: an outage, not a gap
            servo.longest_outage_ns = max(servo.longest_outage_ns, start_ns - servo.last_pulse_ns)
        elif servo.pulses:
            servo.longest_gap_ns = max(servo.longest_gap_ns, start_ns - servo.last_pulse_ns)
        servo.powered_off = False
        servo.pulses += 1
        servo.last_pulse_ns = start_ns
        units = round(width_ns / 800)
        servo.target = servo.angle_of(units)
        rec = self.records[mid]
        stamp = self.stamps[mid]
        if not rec.states:  # the first pulse holds R^0 ...
            state_of, tn_of = self._readers[mid]
            tn = tn_of(stamp)
            if 0 < tn <= 7:  # ... unless it joined a robot that had moved on (no JOIN answered
                # in time: it took the first REQ(h)); it held R^0, unshown, until transition tn
                r0 = int(self.build.module(mid).initial_state)
                rec.states += [r0] * tn
                rec.times_ns += [start_ns] * tn
            rec.states.append(state_of(stamp))
            rec.times_ns.append(start_ns)
            rec.last_tn = tn
        else:  # a transition's time is the first pulse of its new state
            self._observe(mid, stamp)
        if self._dies_at_pulse(mid, stamp, after=True):
            self._kill(mid, stamp, start_ns)

    def _observe(self, mid: ModuleId, stamp: Stamp) -> None:
        rec = self.records[mid]
        if rec.last_tn is None:
            return
        state_of, tn_of = self._readers[mid]
        tn = tn_of(stamp)
        if rec.rejoining:
            self._rejoin(mid, tn, state_of(stamp), stamp.t)
            return
        if tn != rec.last_tn:
            rec.last_tn = tn
            rec.states.append(state_of(stamp))
            rec.times_ns.append(stamp.t)
            if mid == self.reference and self.sim is not None:
                self.path.append(self._disc_xy())

    def _rejoin(self, mid: ModuleId, tn: int, state: int, t_ns: int) -> None:
        """The first pulse of a module booted again (``--reset``): it shows the state of the
        transition ``tn`` (mod 8) it rejoined at, taken as the one nearest its neighbours' latest
        transitions (they are at most two apart from it, docs/twin.md; its own record's end when
        every neighbour is gone). The record restarts there; transitions it skipped while it was
        off (a long outage: its neighbours went on without it) are padded with ``OFF_STATE``
        and no time. A program still joining (tn > 7) is not recorded."""
        if tn > 7:
            return
        rec = self.records[mid]
        end = len(rec.states)
        peers = {p for (m, _), ends in self.wires.items() if m == mid for p, _ in ends}
        near = [len(self.records[p].states) - 1 for p in peers if p in self.stamps]
        anchor = max(near) if near else end
        at = min((t for t in range(max(0, anchor - 4), anchor + 5) if t % 8 == tn),
                 key=lambda t: abs(t - anchor))  # fmt: skip
        rec.before.append(list(rec.states))
        del rec.states[at:]
        del rec.times_ns[at:]
        pad = at - len(rec.states)
        rec.states += [OFF_STATE] * pad
        rec.times_ns += [-1] * pad
        rec.states.append(state)
        rec.times_ns.append(t_ns)
        rec.last_tn = tn
        rec.rejoining = False
        rec.rejoined.append(at)

    def run(
        self,
        transitions: int,
        *,
        timeout_s: float | None = None,
        on_chunk: Callable[[RobotTwin], None] | None = None,
        progress: Callable[[int], object] | None = None,
    ) -> TwinResult:
        """Run until every live module made ``transitions`` transitions (plus one more for the
        reference module, to close the last path point), or ``timeout_s`` of virtual time."""
        if self.reference is None:
            raise InputError("every module failed: nothing runs")
        limit = timeout_s if timeout_s is not None else self.stall_limit_s(transitions)
        limit_ns = int(limit * NS)
        chunk_ns = CHUNK_STEPS * self.dt_ns
        ref = self.records[self.reference]
        done_before = 0
        while self.t_ns < limit_ns:
            self.perturb.advance(self, self.t_ns + chunk_ns)  # issue 12 §1 (power events)
            self._apply_servos()
            if self.sim is not None:
                import mujoco

                mujoco.mj_step(self.sim.model, self.sim.data, nstep=CHUNK_STEPS)
            self.t_ns += chunk_ns
            if on_chunk is not None:
                on_chunk(self)
            if not self.stamps:
                break
            done = min(len(self.records[m].states) for m in self.stamps)
            if progress is not None and done > done_before:
                progress(min(done, transitions + 1) - min(done_before, transitions + 1))
                done_before = done
            if done >= transitions + 1 and (self.sim is None or len(ref.states) >= transitions + 2):
                break
        return self._result(transitions)

    def stall_limit_s(self, transitions: int) -> float:
        """Virtual seconds after which a run that has not made ``transitions`` counts as
        stalled: three times the nominal period (the build's, or the manifest's estimate if
        longer) per transition, times the slowest stamp's timing factor, after the latest
        power-up and every outage, plus twice the power-up window (a neighbour dead from
        power-up is waited for that long, counted in lower bounds of tries), so the NN relay
        at timing scale 3 (~2 s a transition) still completes."""
        estimate = max(
            (m.timing.nominal_transition_s for m in self.build.manifest.modules), default=0.0
        )
        period = max(self.build.period, estimate)
        p, draws = self.perturb.perturbation, self.perturb.draws.values()
        slow = max([1.0, *(d.speed(p.timing_scale) for d in draws)])
        start = max([0.0, *(d.start_s for d in draws)])
        outages = sum(r.off_s for r in p.resets)
        window = self.build.manifest.link.power_up_window_ms / 1000
        return (transitions + 3) * period * 3 * slow + start + outages + 2 * window * slow + 1.0

    def _result(self, transitions: int) -> TwinResult:
        states: dict[ModuleId, list[int]] = {}
        periods: dict[ModuleId, list[float]] = {}
        stalled = []
        for mid in self.order:
            rec = self.records[mid]
            if mid in self.failed:
                states[mid] = rec.states * (transitions + 1)
                continue
            if mid in self.died:  # holds its last state S^T for ever
                rec_states = rec.states + rec.states[-1:] * (transitions + 1 - len(rec.states))
                states[mid] = rec_states[: transitions + 1]
            else:
                states[mid] = rec.states[: transitions + 1]
            periods[mid] = [
                (b - a) / NS
                for a, b in zip(rec.times_ns[1:], rec.times_ns[2:], strict=False)
                if a >= 0 and b >= 0  # not across a reset module's skipped transitions
            ][: max(0, transitions - 1)]
            if len(states[mid]) < transitions + 1:
                stalled.append(mid)
        path = np.array(self.path[: transitions + 1], dtype=float).reshape(-1, 2)
        running = {m: self.records[m].times_ns for m in self.order if m in self.stamps}
        moving_s, running_p = running_periods(running, transitions)
        gaps = {mid: s.longest_gap_ns / NS for mid, s in self.servos.items() if mid in self.ran}
        outages = {
            m: s.longest_outage_ns / NS for m, s in self.servos.items() if s.longest_outage_ns
        }
        announcements = {
            mid: announce.first_line(bytes(stamp.debug)) for mid, stamp in self.ran.items()
        }
        return TwinResult(
            states=states,
            path=path,
            periods=periods,
            servo_gaps=gaps,
            stalled=stalled,
            announcements=announcements,
            virtual_seconds=self.t_ns / NS,
            instructions=sum(s.instructions for s in self.ran.values()),
            moving_s=moving_s,
            running_periods=running_p,
            servo_outages=outages,
        )


class GlobalSchedulerTwin(RobotTwin):
    """The twin on the scheduler the local one replaced (:func:`hil_mock.schedule.
    advance_globally`): the reference tests/test_twin_scheduler.py and bench/twin.py compare
    it with, record for record and in speed."""

    def _advance_stamps(self, limit_ns: int) -> None:
        advance_globally(self, limit_ns)
