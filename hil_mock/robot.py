"""The robot twin: one virtual BS2sx per module, wired as the build says, driving MuJoCo.

Every module runs its own EEPROM image on the token interpreter (:mod:`hil_mock.stamp`).
The modules share one virtual time line. A conservative scheduler always advances the stamp
that is furthest behind, and never past the next stamp's horizon, so a byte a module sends
reaches exactly the neighbours that were listening (SERIN) when its start bit began — a BS2sx
has no receive buffer, so a byte nobody listens to is lost, as on the robot.

Each servo is an actuator of the MuJoCo robot of ``bstool simulate``: a PULSOUT on the servo pin
sets its target angle through the module's calibration (the inverse of the build's state →
pulse table). A servo that gets no pulse for :data:`LIMP_AFTER_S` goes limp (no torque) until
the next pulse. Physics advances in chunks of :data:`CHUNK_STEPS` MuJoCo steps; the stamps are
advanced to the end of each chunk first (docs/twin.md).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module
from hil_mock.perturb import Perturbation, PerturbRun  # issue 12 §1
from hil_mock.stamp import NEVER, Stamp, StampIO, Status

LIMP_AFTER_S = 0.06
"""An analog hobby servo holds its position for a frame or two after the last pulse, then stops
driving; 60 ms (3 frames of 20 ms) is the threshold used here."""
CHUNK_STEPS = 5
"""MuJoCo steps per scheduling chunk (10 ms at the 2 ms step): shorter than one servo frame."""
NS = 1_000_000_000


@dataclass
class Build:
    """A compile output directory: manifest.json and the slot images it names."""

    root: Path
    manifest: dict[str, Any]

    @property
    def legs(self) -> int:
        return int(self.manifest["robot"]["legs"])

    @property
    def modules(self) -> int:
        return int(self.manifest["robot"]["modules"])

    @property
    def period(self) -> float:
        return float(self.manifest["period_s"])

    def module(self, mid: ModuleId) -> dict[str, Any]:
        for m in self.manifest["modules"]:
            if m["module"] == str(mid):
                return dict(m)
        raise InputError(f"module {mid} is not in the build {self.root}")

    def images(self, mid: ModuleId) -> dict[int, bytes]:
        """Slot number → 2048-byte image of a module, read from the build."""
        out = {}
        for slot in self.module(mid)["slots"]:
            if "eeprom" not in slot:
                raise InputError(
                    f"{self.root}: module {mid} slot {slot['slot']} was not tokenized",
                    hint="re-run `bstool compile` with the tokenizer installed",
                )
            out[int(slot["slot"])] = (self.root / slot["eeprom"]).read_bytes()
        return out


def load_build(path: str | Path) -> Build:
    """Read ``path/manifest.json`` (a ``bstool compile`` output)."""
    root = Path(path)
    man = root / "manifest.json"
    if not man.is_file():
        raise InputError(
            f"{root} is not a bstool build (no manifest.json)", hint="run `bstool compile` first"
        )
    try:
        manifest = json.loads(man.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"{man}:{exc.lineno}:{exc.colno}: malformed JSON: {exc.msg}") from None
    if manifest.get("format") != "bstool.build/1":
        raise InputError(f"{man}: expected format bstool.build/1, got {manifest.get('format')!r}")
    return Build(root, manifest)


class _Eeprom8:
    """Eight slots of bytes (what a module's EEPROM holds after flashing)."""

    def __init__(self, images: Mapping[int, bytes]) -> None:
        self.slots = [bytearray(images.get(n, bytes(2048))) for n in range(8)]

    def read_slot(self, slot: int) -> bytes:
        return bytes(self.slots[slot])

    def write_byte(self, slot: int, addr: int, value: int) -> None:
        self.slots[slot][addr] = value


@dataclass
class ServoTrack:
    """One module's servo as the twin sees it."""

    actuator: int
    pin: int
    widths: np.ndarray  # PULSOUT units, sorted ascending
    angles: np.ndarray  # radians for those widths
    target: float
    last_pulse_ns: int = -(10**15)
    longest_gap_ns: int = 0
    pulses: int = 0
    limp: bool = False

    def angle_of(self, units: int) -> float:
        return float(np.interp(units, self.widths, self.angles))


@dataclass
class ModuleRecord:
    """What one module did: its states and when it made its transitions. A transition is seen
    at the first servo pulse after the module's transition counter moved: the moment its servo
    gets the new target (every program pulses its servo at least every 25 ms)."""

    states: list[int] = field(default_factory=list)
    times_ns: list[int] = field(default_factory=list)
    last_tn: int | None = None


@dataclass
class TwinResult:
    states: dict[ModuleId, list[int]]  # observed R^0..R^T per module
    path: np.ndarray  # (T+1, 2): disc xy when the reference module started transitions 1..T+1
    periods: dict[ModuleId, list[float]]  # seconds between a module's transitions
    servo_gaps: dict[ModuleId, float]  # longest time between two servo pulses, seconds
    stalled: list[ModuleId]
    announcements: dict[ModuleId, str]
    virtual_seconds: float
    instructions: int

    @property
    def displacement(self) -> tuple[float, float]:
        if len(self.path) < 2:  # run without physics: no path
            return (0.0, 0.0)
        d = self.path[-1] - self.path[0]
        return float(d[0]), float(d[1])

    @property
    def distance(self) -> float:
        return math.hypot(*self.displacement)

    def state_array(self, legs: int, modules: int, transitions: int) -> np.ndarray:
        """(T+1, n, m) like ``bstool states`` (modules that stalled are padded with -1)."""
        out = -np.ones((transitions + 1, legs, modules), dtype=np.int64)
        for mid, seq in self.states.items():
            k = min(len(seq), transitions + 1)
            out[:k, mid.leg, mid.module] = seq[:k]
        return out

    def period_stats(self) -> tuple[float, float]:
        """Mean and standard deviation of every module's transition period (seconds)."""
        allp = [p for ps in self.periods.values() for p in ps]
        if not allp:
            return math.nan, math.nan
        return float(np.mean(allp)), float(np.std(allp))


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


def _ram_reader(spec: Any) -> Callable[[Stamp], int]:
    """A reader of one RAM variable given as ["nib"|"byte"|"word"|"bit", index]."""
    kind, index = spec
    index = int(index)
    if kind == "nib":
        return lambda s: s.memory.nib(index)
    if kind == "byte":
        return lambda s: s.memory.byte(index)
    if kind == "word":
        return lambda s: s.memory.word(index)
    if kind == "bit":
        return lambda s: s.memory.bit(index)
    raise InputError(f"unknown RAM variable kind {kind!r} in the build's ram_map")


def _wires(
    build: Build, cut: Iterable[tuple[ModuleId, ModuleId]]
) -> dict[tuple[ModuleId, int], list[tuple[ModuleId, int]]]:
    """(module, pin) -> the (module, pin) ends it is wired to, without the ``cut`` wires."""
    ends = [
        (parse_module(w["master"]), int(w["master_pin"]), parse_module(w["slave"]),
         int(w["slave_pin"]))
        for w in build.manifest["links"]
    ]  # fmt: skip
    pairs = list(cut)
    cuts = {frozenset(c) for c in pairs}
    wired = {frozenset((a, b)) for a, _, b, _ in ends}
    for a, b in pairs:
        if frozenset((a, b)) not in wired:
            raise InputError(
                f"cannot cut {a}-{b}: no wire joins these modules in this build",
                hint="WIRING.md lists the wires",
            )
    wires: dict[tuple[ModuleId, int], list[tuple[ModuleId, int]]] = {}
    for a, pin_a, b, pin_b in ends:
        if frozenset((a, b)) not in cuts:
            wires.setdefault((a, pin_a), []).append((b, pin_b))
            wires.setdefault((b, pin_b), []).append((a, pin_a))
    return wires


class RobotTwin:
    """30 virtual modules (or n·m) wired by the build, with the MuJoCo robot as their body.

    ``eeproms`` (module → anything with ``read_slot``/``slot``, e.g. a flashed
    :class:`hil_mock.eeprom.Eeprom`) replaces the build's images, so a robot flashed through the
    programming protocol runs exactly what was flashed. ``failed`` modules never run (silent on
    their links) and their servo holds the R^0 angle (the paper's failed module: a fixed state);
    with ``limp_failed`` it goes limp instead. ``die`` maps modules to the transition T at which
    they die during the run: the stamp stops for good once it has shown S^T on its servo and sent
    S^T to its neighbours (:meth:`_dies_at_pulse`, docs/twin.md); its servo then holds S^T (limp
    with ``limp_failed``). ``cut`` removes links. ``noise`` is the chance that
    a byte on a link is hit (half of the hits drop it, half flip one bit), drawn from ``seed``.
    """

    def __init__(
        self,
        build: Build,
        *,
        eeproms: Mapping[ModuleId, object] | None = None,
        failed: Iterable[ModuleId | str] = (),
        die: Mapping[ModuleId, int] | Mapping[str, int] | None = None,
        limp_failed: bool = False,
        cut: Iterable[tuple[ModuleId, ModuleId]] = (),
        noise: float = 0.0,
        seed: int = 0,
        physics: bool = True,
        perturb: Perturbation | None = None,  # issue 12 §1
    ) -> None:
        self.build = build
        if not 0.0 <= noise <= 1.0:
            raise InputError(f"link noise must be a probability in 0..1, got {noise}")
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.noise_events = {"flipped": 0, "dropped": 0}
        legs, modules = build.legs, build.modules
        self.order = [ModuleId(i, j) for i in range(legs) for j in range(modules)]
        self.failed = {
            m if isinstance(m, ModuleId) else parse_module(m, legs, modules) for m in failed
        }
        self.die: dict[ModuleId, int] = {}
        for key, when in (die or {}).items():
            mid = key if isinstance(key, ModuleId) else parse_module(key, legs, modules)
            if int(when) < 0:
                raise InputError(f"module {mid} cannot die at transition {when}: T must be >= 0")
            if mid in self.failed:
                raise InputError(f"module {mid} is both failed from power-up and dying at {when}")
            self.die[mid] = int(when)
        self.limp_failed = limp_failed
        self.died: dict[ModuleId, int] = {}  # module -> virtual ns when its stamp stopped
        self._killed = False
        self._nn = str(build.manifest.get("controller", {}).get("model", "")).startswith("nn")
        self.wires = _wires(build, cut)
        self.stamps: dict[ModuleId, Stamp] = {}
        self.records: dict[ModuleId, ModuleRecord] = {m: ModuleRecord() for m in self.order}
        self.servos: dict[ModuleId, ServoTrack] = {}
        self._readers: dict[ModuleId, tuple[Callable[[Stamp], int], Callable[[Stamp], int]]] = {}
        self._init_physics(physics)
        for mid in self.order:
            info = build.module(mid)
            self.servos[mid] = self._servo(mid, info)
            if mid in self.failed:
                r0 = int(info["initial_state"])
                self.records[mid].states.append(r0)
                self.servos[mid].limp = limp_failed
                continue
            source = eeproms.get(mid) if eeproms is not None else None
            store = _Eeprom8(build.images(mid)) if source is None else source
            self.stamps[mid] = Stamp(store, io=_TwinIO(self, mid), name=mid.label)
            ram = info.get("ram_map")
            if not ram:
                raise InputError(
                    f"{build.root}: module {mid} has no ram_map in manifest.json",
                    hint="re-run `bstool compile` with this bstool version",
                )
            self._readers[mid] = (_ram_reader(ram["state"]), _ram_reader(ram["tn"]))
        self.ran: dict[ModuleId, Stamp] = dict(self.stamps)  # every stamp that ever ran
        live = [m for m in self.order if m in self.stamps and m not in self.die]
        self.reference = live[0] if live else next(iter(self.stamps), None)
        self.t_ns = 0
        self.path: list[tuple[float, float]] = []
        self.perturb = PerturbRun.install(self, perturb)  # issue 12 §1: clocks, starts, resets

    # ---- physics --------------------------------------------------------------------------
    def _init_physics(self, physics: bool) -> None:
        self.sim = None
        if not physics:
            self.dt_ns = 2_000_000
            return
        from bstool.robot import RobotSpec
        from bstool.sim.simulator import Simulator

        robot = self.build.manifest["robot"]
        spec = RobotSpec(legs=robot["legs"], modules=robot["modules"], states=robot["states"])
        self.sim = Simulator(spec)
        self.sim.reset(self.sim.data)
        self.dt_ns = round(self.sim.model.opt.timestep * NS)
        self._gain = self.sim.model.actuator_gainprm.copy()
        self._bias = self.sim.model.actuator_biasprm.copy()

    def _servo(self, mid: ModuleId, info: dict[str, Any]) -> ServoTrack:
        from bstool.robot import state_to_angle

        widths = np.array(info["servo"]["pulsout"], dtype=float)
        k = len(widths)
        angles = np.array([state_to_angle(s, k) for s in range(k)])
        order = np.argsort(widths, kind="stable")
        servo_pin = next(p["pin"] for p in info["pins"] if p["use"] == "servo")
        r0 = int(info["initial_state"])
        actuator = mid.leg * self.build.modules + mid.module
        return ServoTrack(actuator, servo_pin, widths[order], angles[order], float(angles[r0]))

    def _apply_servos(self) -> None:
        if self.sim is None:
            return
        model, data = self.sim.model, self.sim.data
        limp_after = int(LIMP_AFTER_S * NS)
        for mid, servo in self.servos.items():
            a = servo.actuator
            if mid in self.stamps:
                servo.limp = self.t_ns - servo.last_pulse_ns > limp_after
            if servo.limp:
                model.actuator_gainprm[a] = 0.0
                model.actuator_biasprm[a] = 0.0
            else:
                model.actuator_gainprm[a] = self._gain[a]
                model.actuator_biasprm[a] = self._bias[a]
                data.ctrl[a] = servo.target

    def _disc_xy(self) -> tuple[float, float]:
        assert self.sim is not None
        q = self.sim.data.qpos
        return (float(q[0]), float(q[1]))

    # ---- links and servos (called from the stamps' IO) ------------------------------------
    def _route(self, mid: ModuleId, pin: int, value: int, start_ns: int, mode: int) -> None:
        if self.noise and self.rng.random() < self.noise:
            if self.rng.random() < 0.5:  # the byte is lost (a start bit not seen)
                self.noise_events["dropped"] += 1
                return
            value ^= 1 << int(self.rng.integers(8))  # one bit flipped on the wire
            self.noise_events["flipped"] += 1
        tx_bit_ns = self.stamps[mid].clock.bit_ns(mode)  # issue 12 §1: the sender's bit time
        for peer, peer_pin in self.wires.get((mid, pin), ()):
            stamp = self.stamps.get(peer)
            if stamp is not None:
                stamp.deliver_byte(peer_pin, value, start_ns, mode, tx_bit_ns)

    def _dies_at_pulse(self, mid: ModuleId, stamp: Stamp, after: bool) -> bool:
        """Whether a dying module stops at this servo pulse (``after``: once it went out).

        The module dies once its servo shows S^T and its neighbours have had S^T. A CA program
        shows S^T, then exchanges it, then looks up S^(T+1): it stops at the first pulse of
        S^(T+1), before it goes out (tn has changed T + 1 times; nothing happens on a link
        between the lookup and that pulse). An NN program relays S^T downstream first and then
        shows it: it stops right after the first pulse of S^T (tn has changed T times)."""
        when = self.die.get(mid)
        if when is None:
            return False
        rec = self.records[mid]
        if self._nn:
            return after and len(rec.states) == when + 1
        return (
            not after
            and len(rec.states) == when + 1
            and self._readers[mid][1](stamp) != rec.last_tn
        )

    def _kill(self, mid: ModuleId, stamp: Stamp, t_ns: int) -> None:
        stamp.status = Status.STOPPED  # for good: ends the running run_until at once
        stamp.brk = True
        del self.stamps[mid]
        self.died[mid] = t_ns
        self.servos[mid].limp = self.limp_failed
        self._killed = True

    def _servo_pulse(self, mid: ModuleId, servo: ServoTrack, start_ns: int, width_ns: int) -> None:
        if mid not in self.stamps:
            return
        if self._dies_at_pulse(mid, self.stamps[mid], after=False):
            self._kill(mid, self.stamps[mid], start_ns)
            return
        if servo.pulses:
            servo.longest_gap_ns = max(servo.longest_gap_ns, start_ns - servo.last_pulse_ns)
        servo.pulses += 1
        servo.last_pulse_ns = start_ns
        units = round(width_ns / 800)
        servo.target = servo.angle_of(units)
        rec = self.records[mid]
        stamp = self.stamps[mid]
        if not rec.states:  # the first pulse holds R^0
            state_of, tn_of = self._readers[mid]
            rec.states.append(state_of(stamp))
            rec.times_ns.append(start_ns)
            rec.last_tn = tn_of(stamp)
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
        if tn != rec.last_tn:
            rec.last_tn = tn
            rec.states.append(state_of(stamp))
            rec.times_ns.append(stamp.t)
            if mid == self.reference and self.sim is not None:
                self.path.append(self._disc_xy())

    # ---- scheduling -----------------------------------------------------------------------
    def _advance_stamps(self, limit_ns: int) -> None:
        """Run every stamp up to ``limit_ns``, always the one furthest behind first."""
        stamps = list(self.stamps.items())
        self._killed = False
        while True:
            if self._killed:  # a module died in the last step
                stamps = list(self.stamps.items())
                self._killed = False
            best: tuple[ModuleId, Stamp] | None = None
            h1 = h2 = NEVER
            for item in stamps:
                h = item[1].horizon
                if h < h1:
                    h2, h1, best = h1, h, item
                elif h < h2:
                    h2 = h
            if best is None or h1 >= limit_ns:
                return
            stamp = best[1]
            if stamp.status is Status.WAITING:
                stamp.expire_wait()
            else:
                stamp.run_until(min(limit_ns, max(h2, h1 + 1)))

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
        period = self.build.period
        limit = timeout_s if timeout_s is not None else (transitions + 3) * period * 3 + 1.0
        limit_ns = int(limit * NS)
        chunk_ns = CHUNK_STEPS * self.dt_ns
        ref = self.records[self.reference]
        done_before = 0
        while self.t_ns < limit_ns:
            self.perturb.advance(self, self.t_ns + chunk_ns)  # issue 12 §1 (was _advance_stamps)
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
                (b - a) / NS for a, b in zip(rec.times_ns[1:], rec.times_ns[2:], strict=False)
            ][: max(0, transitions - 1)]
            if len(states[mid]) < transitions + 1:
                stalled.append(mid)
        path = np.array(self.path[: transitions + 1], dtype=float).reshape(-1, 2)
        gaps = {mid: s.longest_gap_ns / NS for mid, s in self.servos.items() if mid in self.ran}
        announcements = {
            mid: bytes(stamp.debug).decode("ascii", "replace").split("\r")[0]
            for mid, stamp in self.ran.items()
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
        )
