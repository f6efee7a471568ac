"""A twin as unkind as real stamps (issue 12 §1): per-module timing, clocks, power-up, resets.

:class:`Perturbation` holds the options of ``bstool twin`` and ``python -m hil_mock serve``
(``--timing-scale``, ``--timing-spread``, ``--clock-spread``, ``--start-spread``, ``--reset``,
``--item-time``), validated on construction (:class:`~bstool.errors.InputError`). :func:`draw`
draws every module's factors and power-up time from ``--seed`` (a stream of its own, so the
link noise draws are unchanged). :class:`PerturbRun` applies them to a
:class:`~hil_mock.robot.RobotTwin` (its three hooks: ``PerturbRun.install`` at the end of
``__init__``, ``advance`` instead of ``_advance_stamps`` in ``run``, and the sender's bit time
in ``_route``) and reports what was drawn (``report``, the ``perturbations`` object of
``--json``). The models and their sources: docs/twin.md, "Perturbations".
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import click
import numpy as np

from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module

if TYPE_CHECKING:
    from bstool.timingfile import TimingModel
    from hil_mock.stamp import Stamp
    from hil_mock.stamp.clock import StampClock

RobotTwin = Any
"""A :class:`hil_mock.robot.RobotTwin` (not imported: it imports this module, and the sibling
modules of hil_mock stay acyclic). Used: build, order, stamps, die, reference, servos,
records, _readers, _advance_stamps, _killed."""

NS = 1_000_000_000
TIMING_SCALE = (0.5, 3.0)
TIMING_SPREAD = (0.0, 0.5)
CLOCK_SPREAD = (0.0, 0.1)
START_SPREAD_S = (0.0, 60.0)
RESET_OFF_S = (0.0, 60.0)
ITEM_TIME_US = (0.0, 2000.0)
DRAW_STREAM = 12  # the perturbation draws' own stream of ``--seed`` (issue 12)
_RESET = re.compile(r"\s*(\d+\.\d+)\s*@\s*(\d+(?:\.\d*)?|\.\d+)\s*\+\s*(\d+(?:\.\d*)?|\.\d+)\s*")


@dataclass(frozen=True)
class Reset:
    """Module ``module`` (a label, resolved against the robot by :class:`PerturbRun`) loses
    power at ``at_s`` of virtual time and is off for ``off_s``."""

    module: str
    at_s: float
    off_s: float

    def __str__(self) -> str:
        return f"{self.module}@{self.at_s:g}+{self.off_s:g}"


def parse_reset(text: str) -> Reset:
    """``L.M@T+OFF`` (seconds) → :class:`Reset`."""
    m = _RESET.fullmatch(text)
    if m is None:
        raise InputError(
            f"bad --reset {text!r}: expected L.M@T+OFF",
            hint="e.g. --reset 0.0@3+0.5: module 0.0 loses power at 3 s for 0.5 s",
        )
    module, at, off = m.group(1), float(m.group(2)), float(m.group(3))
    lo, hi = RESET_OFF_S
    if not lo < off <= hi:
        raise InputError(
            f"bad --reset {text!r}: the module must stay off for more than {lo:g} and at most "
            f"{hi:g} s, not {off:g}",
            hint="e.g. --reset 0.0@3+0.5",
        )
    return Reset(module, at, off)


def _check_range(name: str, value: float, bounds: tuple[float, float], unit: str = "") -> None:
    lo, hi = bounds
    if not (math.isfinite(value) and lo <= value <= hi):
        raise InputError(
            f"{name} must be in {lo:g}..{hi:g}{unit}, not {value:g}",
            hint=f"give {name} a value from {lo:g} to {hi:g}",
        )


@dataclass(frozen=True)
class Perturbation:
    """The options. Neutral values (the defaults) leave the twin exactly as without them."""

    timing_scale: float = 1.0
    timing_spread: float = 0.0
    clock_spread: float = 0.0
    start_spread: float = 0.0
    resets: tuple[Reset, ...] = ()
    item_time_us: float | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        _check_range("--timing-scale", self.timing_scale, TIMING_SCALE)
        _check_range("--timing-spread", self.timing_spread, TIMING_SPREAD)
        _check_range("--clock-spread", self.clock_spread, CLOCK_SPREAD)
        _check_range("--start-spread", self.start_spread, START_SPREAD_S, " s")
        if self.item_time_us is not None:
            _check_range("--item-time", self.item_time_us, ITEM_TIME_US, " us")
        for r in self.resets:
            if not (math.isfinite(r.at_s) and r.at_s >= 0):
                raise InputError(f"bad --reset {r}: T must be >= 0 s")
            _check_range(f"--reset {r}: OFF", r.off_s, RESET_OFF_S, " s")

    @property
    def neutral(self) -> bool:
        return self == Perturbation(seed=self.seed)

    def options(self) -> dict[str, Any]:
        """The options as given (JSON)."""
        return {
            "seed": self.seed,
            "timing_scale": self.timing_scale,
            "timing_spread": self.timing_spread,
            "clock_spread": self.clock_spread,
            "start_spread_s": self.start_spread,
            "item_time_us": self.item_time_us,
            "resets": [str(r) for r in self.resets],
        }


@dataclass(frozen=True)
class ModuleDraw:
    """What was drawn for one module: its own timing factor (``--timing-spread``), its
    resonator factor (``--clock-spread``, > 1 = slow) and its power-up time."""

    timing: float
    resonator: float
    start_s: float

    def speed(self, scale: float) -> float:
        """Factor on every instruction and fixed overhead: scale × own timing × resonator."""
        return scale * self.timing * self.resonator


def draw(p: Perturbation, modules: Sequence[ModuleId]) -> dict[ModuleId, ModuleDraw]:
    """Every module's draws, in ``modules`` order, from ``p.seed``. All three arrays are drawn
    whatever the options (a spread of 0 draws exactly 1.0 or 0.0), so one option's draws do
    not depend on the others'."""
    rng = np.random.default_rng([DRAW_STREAM, p.seed & (2**63 - 1)])
    n = len(modules)
    timing = rng.uniform(1.0 - p.timing_spread, 1.0 + p.timing_spread, n)
    resonator = rng.uniform(1.0 - p.clock_spread, 1.0 + p.clock_spread, n)
    start = rng.uniform(0.0, p.start_spread, n)
    return {
        m: ModuleDraw(float(timing[i]), float(resonator[i]), float(start[i]))
        for i, m in enumerate(modules)
    }


def stamp_clock(p: Perturbation, d: ModuleDraw, model: TimingModel | None = None) -> StampClock:
    """The :class:`~hil_mock.stamp.clock.StampClock` of a module with draws ``d`` on the
    nominal timing ``model`` (None: the estimate)."""
    from hil_mock.stamp.clock import StampClock

    item = None if p.item_time_us is None else round(p.item_time_us * 1000)
    clock = StampClock(speed=d.speed(p.timing_scale), resonator=d.resonator, item_ns=item)
    return clock.with_model(model)


@dataclass
class PerturbRun:
    """The perturbations applied to one twin: clocks and start times set, resets scheduled."""

    perturbation: Perturbation
    draws: dict[ModuleId, ModuleDraw] = field(default_factory=dict)
    resets: list[tuple[ModuleId, Reset]] = field(default_factory=list)
    events: list[tuple[int, int, str, ModuleId]] = field(default_factory=list)
    boots: dict[ModuleId, list[float]] = field(default_factory=dict)  # virtual s of each boot
    offs: dict[ModuleId, list[float]] = field(default_factory=dict)  # virtual s of each loss
    off_stamps: dict[ModuleId, Stamp] = field(default_factory=dict)  # powered off now
    stamps: list[Stamp] = field(default_factory=list)  # every stamp of the twin (counters)

    @classmethod
    def install(cls, twin: RobotTwin, p: Perturbation | None) -> PerturbRun:
        """Apply ``p`` to ``twin`` (right after its stamps were made)."""
        run = cls(p or Perturbation())
        run.stamps = list(twin.stamps.values())
        if p is None or p.neutral:
            return run
        legs, modules = twin.build.legs, twin.build.modules
        run.draws = draw(p, twin.order)
        for mid, stamp in twin.stamps.items():
            d = run.draws[mid]
            stamp.set_clock(stamp_clock(p, d, twin.timing))
            stamp.t = round(d.start_s * NS)  # nothing runs before power-up; lines released
        spans: dict[ModuleId, list[tuple[float, float]]] = {}
        for r in p.resets:
            try:
                mid = parse_module(r.module, legs, modules)
            except InputError as exc:
                raise InputError(f"--reset {r}: {exc}", hint=exc.hint) from None
            if mid not in twin.stamps:
                raise InputError(f"--reset {r}: module {mid} is failed (--fail): it never runs")
            if mid in twin.die:
                raise InputError(
                    f"--reset {r}: module {mid} also dies (--die); give one fault per module"
                )
            on_at = max(r.at_s, run.draws[mid].start_s)
            for a, b in spans.get(mid, []):
                if on_at < b and a < on_at + r.off_s:
                    raise InputError(f"--reset {r}: overlaps another reset of module {mid}")
            spans.setdefault(mid, []).append((on_at, on_at + r.off_s))
            run.resets.append((mid, r))
            off_ns = round(on_at * NS)
            run.events.append((off_ns, len(run.events), "off", mid))
            run.events.append((off_ns + round(r.off_s * NS), len(run.events), "on", mid))
        run.events.sort()
        reset_mods = {m for m, _ in run.resets}
        if twin.reference in reset_mods:  # the path follows a module that keeps running
            live = [m for m in twin.order if m in twin.stamps and m not in twin.die]
            steady = [m for m in live if m not in reset_mods]
            twin.reference = steady[0] if steady else twin.reference
        return run

    # ---- scheduling ---------------------------------------------------------------------------
    def advance(self, twin: RobotTwin, limit_ns: int) -> None:
        """``twin._advance_stamps(limit_ns)``, with the power events before it applied at
        their times (every stamp has reached the event time when it happens)."""
        while self.events and self.events[0][0] <= limit_ns:
            t_ns, _, kind, mid = self.events.pop(0)
            twin._advance_stamps(t_ns)
            if kind == "off":
                self._power_off(twin, mid, t_ns)
            else:
                self._power_on(twin, mid, t_ns)
        twin._advance_stamps(limit_ns)

    def _power_off(self, twin: RobotTwin, mid: ModuleId, t_ns: int) -> None:
        from hil_mock.stamp import Status

        stamp = twin.stamps.pop(mid, None)
        if stamp is None:
            return
        stamp.status = Status.STOPPED  # no instruction, no byte heard or sent, no pulse
        stamp.wait = None
        stamp.brk = True
        twin.servos[mid].limp = True  # no pulses: the servo stops driving
        twin.servos[mid].powered_off = True  # its next pulse ends an outage, not a servo gap
        twin._killed = True  # the scheduler re-reads the stamps
        self.offs.setdefault(mid, []).append(t_ns / NS)
        self.off_stamps[mid] = stamp

    def _power_on(self, twin: RobotTwin, mid: ModuleId, t_ns: int) -> None:
        stamp = self.off_stamps.pop(mid, None)
        if stamp is None:
            return
        stamp.power_cycle()  # RAM and scratchpad cleared, pins inputs, slot 0 from EEPROM
        stamp.t = t_ns
        stamp.brk = False
        rec = twin.records[mid]
        rec.last_tn = twin._readers[mid][1](stamp)  # the new program's count starts afresh
        rec.rejoining = True  # its next pulse says which transition it rejoined at
        order = {m: i for i, m in enumerate(twin.order)}
        stamps = dict(twin.stamps)
        stamps[mid] = stamp
        twin.stamps.clear()
        twin.stamps.update(sorted(stamps.items(), key=lambda kv: order[kv[0]]))
        twin._killed = True
        self.boots.setdefault(mid, []).append(t_ns / NS)

    # ---- report -------------------------------------------------------------------------------
    def reset_modules(self) -> set[ModuleId]:
        return {m for m, _ in self.resets}

    def report(self) -> dict[str, Any]:
        """The options, what was drawn and what happened (the ``perturbations`` of --json)."""
        from hil_mock.stamp.clock import UART_TOLERANCE

        out = draws_json(self.perturbation, self.draws)
        out["uart_tolerance"] = UART_TOLERANCE
        out["power"] = [
            {
                "module": str(m),
                "reset": str(r),
                "off_s": self.offs.get(m, []),
                "booted_s": self.boots.get(m, []),
            }
            for m, r in self.resets
        ]
        stamps = self.stamps
        out["bytes_missed"] = sum(s.rx_missed for s in stamps)
        out["bytes_mismatched"] = sum(s.rx_mismatched for s in stamps)
        return out


# ---- python -m hil_mock serve -----------------------------------------------------------------
def serve_draws(p: Perturbation, modules: Sequence[ModuleId]) -> dict[ModuleId, ModuleDraw]:
    """The draws of ``serve``'s modules. Served stamps are reset by their host, one at a time, so
    a reset at a virtual time of a robot run has no meaning there."""
    if p.resets:
        raise click.UsageError("--reset needs a robot run in virtual time: use `bstool twin`")
    return draw(p, modules)


def perturb_runner(
    runner: object, p: Perturbation, d: ModuleDraw, model: TimingModel | None = None
) -> None:
    """Give a served module's interpreter preview (``InterpreterRunner``) its clock (on the
    nominal timing ``model``) and start."""
    if hasattr(runner, "clock") and hasattr(runner, "start_s"):
        runner.clock = stamp_clock(p, d, model)
        runner.start_s = d.start_s


def draws_json(p: Perturbation, draws: dict[ModuleId, ModuleDraw]) -> dict[str, Any]:
    """The options and draws (serve prints them on stderr)."""
    out = p.options()
    out["modules"] = {
        str(m): {"timing": d.timing, "resonator": d.resonator,
                 "speed": d.speed(p.timing_scale), "start_s": d.start_s}
        for m, d in draws.items()
    }  # fmt: skip
    return out


# ---- command-line options ---------------------------------------------------------------------
Decorator = Callable[[Callable[..., Any]], Callable[..., Any]]


def perturb_options(*, add_seed: bool = False, usage_errors: bool = False) -> Decorator:
    """Click options of the perturbations; the command gets them as one ``perturb``
    (:class:`Perturbation`) argument. The seed is the command's own ``--seed`` (``add_seed``:
    add one). ``usage_errors``: bad values as click usage errors (for a click program without
    bstool's error handler)."""

    def decorate(func: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(func)
        def wrapper(*args: Any, **kw: Any) -> Any:
            seed = kw.pop("seed") if add_seed else kw.get("seed", 0)
            try:
                kw["perturb"] = Perturbation(
                    timing_scale=kw.pop("timing_scale"),
                    timing_spread=kw.pop("timing_spread"),
                    clock_spread=kw.pop("clock_spread"),
                    start_spread=kw.pop("start_spread"),
                    resets=tuple(parse_reset(r) for r in kw.pop("resets")),
                    item_time_us=kw.pop("item_time"),
                    seed=int(seed or 0),
                )
            except InputError as exc:
                if not usage_errors:
                    raise
                raise click.UsageError(f"{exc} ({exc.hint})" if exc.hint else str(exc)) from None
            return func(*args, **kw)

        opts = _options()
        if add_seed:
            seed_help = "Seed of every random draw."
            opts.append(click.option("--seed", type=int, default=0, help=seed_help))
        command: Callable[..., Any] = wrapper
        for opt in reversed(opts):
            command = opt(command)
        return command

    return decorate


def _options() -> list[Decorator]:
    return [
        click.option(
            "--timing-scale",
            type=float,
            default=1.0,
            show_default=True,
            metavar="F",
            help="Every instruction and fixed overhead of the timing model × F (0.5-3).",
        ),
        click.option(
            "--timing-spread",
            type=float,
            default=0.0,
            show_default=True,
            metavar="P",
            help="Each module's timing × its own factor drawn in [1-P, 1+P] (0-0.5).",
        ),
        click.option(
            "--clock-spread",
            type=float,
            default=0.0,
            show_default=True,
            metavar="P",
            help="Each module's resonator off by a factor drawn in [1-P, 1+P] (0-0.1): "
            "instructions, PAUSE, PULSOUT, SERIN timeouts and bit rate.",
        ),
        click.option(
            "--start-spread",
            type=float,
            default=0.0,
            show_default=True,
            metavar="S",
            help="Each module powers up at a time drawn in [0, S] seconds (0-60).",
        ),
        click.option(
            "--reset",
            "resets",
            multiple=True,
            metavar="L.M@T+OFF",
            help="Module L.M loses power at T s of virtual time for OFF s (servo limp, lines "
            "released), then boots from its EEPROM with RAM cleared; repeatable.",
        ),
        click.option(
            "--item-time",
            type=float,
            default=None,
            metavar="US",
            help="Stamp serial timing: US microseconds (× the module's speed) between two "
            "SERIN/SEROUT items; the receiver listens again US after the stop bit's mid-bit "
            "sample. Default: back-to-back bytes, listening again at the stop bit's end.",
        ),
    ]
