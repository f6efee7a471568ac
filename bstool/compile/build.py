"""Orchestrate a build: load, plan, render, tokenize, describe, and write build/ atomically."""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bstool import buildfile, fileio, outputs, timingfile
from bstool.compile import describe
from bstool.compile.calibration import DEFAULT, Calibration, load_calibration
from bstool.compile.plan import (
    ModulePlan,
    build_plans,
    estimates,
    floor_period_ms,
    min_hold_frames,
    period_ms,
)
from bstool.compile.render import render_module
from bstool.compile.results import ModuleResult, SlotResult
from bstool.compile.timing import CompileTiming
from bstool.compile.wiring import wiring as wiring_md
from bstool.controllers import Controller, controller_hash, load_controller
from bstool.errors import BstoolError, BuildError, InputError, SourceError
from bstool.moduleid import ModuleId, parse_module
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot, resolve
from bstool.timingfile import TimingModel
from bstool.tokenizer import Project, tokenize_source

SLOT_BYTES = buildfile.SLOT_BYTES
FLOOR_SLACK = 0.05
"""A period this much under the estimated floor is still accepted (it runs at the floor): the
estimate is a model's, a few % off the twin (docs/compile.md)."""
RAM_BYTES = describe.RAM_BYTES


@dataclass
class BuildResult:
    out_dir: Path
    controller_hash: str
    modules: list[ModuleResult]
    tokenized: bool
    manifest: buildfile.Manifest


def default_period(legs: int, modules: int, spec: RobotSpec | None = None) -> float:
    """The simulator's transition time for this robot (``RobotSpec.transition_time``: the
    servo's full-range time with margin); ``spec``: a robot file's robot."""
    robot = spec if spec is not None else RobotSpec(legs=legs, modules=modules)
    return float(robot.transition_time)


def ram_estimate(plan: ModulePlan) -> int:
    """Bytes of RAM the declared variables take (26 available): words, bytes, nibs, bits."""
    nibs = 2 + len(plan.known)  # state, tn, nb()/up()
    bits = 1  # booted
    return 2 + 1 + 1 + plan.rx_size + (nibs + 1) // 2 + (bits + 7) // 8


def compile_controller(
    controller: str | os.PathLike[str],
    out_dir: str | os.PathLike[str] = "build",
    *,
    calibration: str | os.PathLike[str] | None = None,
    period: float | None = None,
    modules: Sequence[str] = (),
    tokenize: bool = True,
    progress: bool = False,
    force: bool = False,
    timing: TimingModel | str | os.PathLike[str] | None = None,
    robot: Robot | str | os.PathLike[str] | None = None,
) -> BuildResult:
    """Compile ``controller`` into ``out_dir`` (replaced as a whole, never half-written).

    ``robot``: a robot file (or ``Robot``) to compile for instead of the one the controller
    recorded (default: that one, else the default robot); it sets the default period and is
    recorded in the build.

    ``out_dir`` may be new, empty, or a previous build; anything else is refused unless
    ``force`` (and never when it holds the controller or calibration file).
    ``tokenize=False`` writes the PBASIC sources only (no slot images: flash and the twin
    refuse such a build); the golden tests use it."""
    ctrl = load_controller(controller)
    return compile_loaded(
        ctrl,
        out_dir,
        source_name=Path(controller).name,
        calibration=calibration,
        period=period,
        modules=modules,
        tokenize=tokenize,
        progress=progress,
        force=force,
        protect=(controller,),
        timing=timing,
        robot=robot,
    )


def compile_loaded(
    ctrl: Controller,
    out_dir: str | os.PathLike[str],
    *,
    source_name: str = "controller",
    calibration: str | os.PathLike[str] | None = None,
    period: float | None = None,
    modules: Sequence[str] = (),
    tokenize: bool = True,
    progress: bool = False,
    force: bool = False,
    protect: Sequence[str | os.PathLike[str]] = (),
    timing: TimingModel | str | os.PathLike[str] | None = None,
    robot: Robot | str | os.PathLike[str] | None = None,
) -> BuildResult:
    """Compile a loaded controller (see :func:`compile_controller`). ``timing``: a measured
    timing model or its bstool.timing/1 file, for the timing estimates and the waits computed
    from them (issue 13 §2; default: the estimate)."""
    if timing is not None and not isinstance(timing, TimingModel):
        timing = timingfile.load(timing)
    model = CompileTiming() if timing is None else CompileTiming(timing)
    if robot is not None and not isinstance(robot, Robot):
        protect = (*protect, robot)
    chosen, _note = resolve(robot, ctrl.robot, what=source_name)
    recorded = chosen.to_json() if robot is not None or ctrl.robot is not None else None
    return _compile_loaded(
        ctrl, out_dir, source_name=source_name, calibration=calibration, period=period,
        modules=modules, tokenize=tokenize, progress=progress, force=force, protect=protect,
        model=model, robot=chosen, robot_values=recorded,
    )  # fmt: skip


def _compile_loaded(
    ctrl: Controller,
    out_dir: str | os.PathLike[str],
    *,
    source_name: str,
    calibration: str | os.PathLike[str] | None,
    period: float | None,
    modules: Sequence[str],
    tokenize: bool,
    progress: bool,
    force: bool,
    protect: Sequence[str | os.PathLike[str]],
    model: CompileTiming,
    robot: Robot,
    robot_values: dict[str, Any] | None,
) -> BuildResult:
    out = Path(out_dir)
    protect = (*protect, *((calibration,) if calibration is not None else ()))
    check_output(out, force=force, protect=protect)
    full_hash = controller_hash(ctrl)
    calib: Calibration = (
        DEFAULT if calibration is None else load_calibration(calibration, ctrl.legs, ctrl.modules)
    )
    if period is None:
        period = default_period(ctrl.legs, ctrl.modules, robot.spec)
    if not period > 0:
        raise InputError(f"--period must be > 0 seconds, got {period}")
    only: list[ModuleId] = []
    for text in modules:
        try:
            only.append(parse_module(text, ctrl.legs, ctrl.modules))
        except InputError as exc:
            raise InputError(
                exc.message,
                hint=f"this controller's robot has modules 0.0 .. "
                f"{ctrl.legs - 1}.{ctrl.modules - 1}",
            ) from None
    every = build_plans(ctrl, calib, period, full_hash[:8], model=model)
    nominal = period_ms(every)
    plans = [p for p in every if not only or p.mid in only]
    floor = floor_period_ms(every)
    if period * 1000 < floor * (1 - FLOOR_SLACK):
        raise BuildError(
            f"a period of {period:g} s is too short for {ctrl.model}: its handshakes take about "
            f"{floor / 1000:.3f} s a transition at the fewest hold frames "
            f"({min_hold_frames(every)}; timing model estimate)",
            hint=f"use --period {math.ceil(floor / 10) / 100:.2f} or more",
        )
    results = [
        _module(plan, estimates(plan, nominal), tokenize)
        for plan in tqdm(plans, desc="compile", unit="module", disable=not progress, leave=False)
    ]
    manifest = describe.manifest(
        ctrl, source_name, full_hash, period, results, tokenize, robot_values
    )
    wiring = wiring_md(ctrl, full_hash, results, manifest)
    _write_atomically(out, results, manifest, wiring, ctrl.to_json())
    return BuildResult(out, full_hash, results, tokenize, manifest)


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _module(plan: ModulePlan, timing: dict[str, float], tokenize: bool) -> ModuleResult:
    sources = render_module(plan)
    slots = [
        SlotResult(slot, name, _sha(sources[name].encode()))
        for slot, name in enumerate(plan.slot_files)
    ]
    ram = ram_estimate(plan)
    ram_map: dict[str, tuple[str, int]] | None = None
    if tokenize:
        project = _tokenize(plan, sources)
        for sr in slots:
            image = project.slots[sr.slot]
            sr.program_bytes = int(image.program_bytes)
            sr.data_bytes = int(image.data_bytes)
            sr.eeprom = bytes(image.eeprom)
            sr.packets = b"".join(bytes(r) for r in image.records)
            if sr.program_bytes + sr.data_bytes > SLOT_BYTES:  # pragma: no cover - tokenizer checks
                raise _too_big(plan, sr.slot, sr.program_bytes + sr.data_bytes - SLOT_BYTES)
        ram = max(project.slots[0].variables_used, ram)
        variables = project.slots[0].variables
        ram_map = {
            name.lower(): variables[name.upper()]
            for name in ("state", "tn")
            if name.upper() in variables
        }
    if ram > RAM_BYTES:
        raise BuildError(
            f"{plan.label}: the program needs {ram} bytes of RAM, the BS2sx has {RAM_BYTES}",
            hint="use a robot with fewer modules per leg (NN frames grow with the leg)",
        )
    return ModuleResult(plan, sources, slots, ram, timing, ram_map)


def _too_big(plan: ModulePlan, slot: int, over: int) -> BuildError:
    what = (
        "the rule slice per slot (tables.RULE_SLOTS) or the neighbour count"
        if slot
        else "the number of links (model) or the NN table"
    )
    how = f"{over} bytes over" if over > 0 else "its program and DATA overlap in"
    return BuildError(
        f"{plan.label}: slot {slot} ({plan.slot_files[slot]}) does not fit: {how} "
        f"the {SLOT_BYTES}-byte slot",
        hint=f"reduce {what}; see docs/compile.md (slot layout)",
    )


def _tokenize_sources(sources: dict[str, str]) -> Project:
    """Tokenize a module's project in memory (main.bsx and the slot files it names)."""
    return tokenize_source(sources["main.bsx"], "main.bsx", files=sources)


def _tokenize(plan: ModulePlan, sources: dict[str, str]) -> Project:
    try:
        return _tokenize_sources(sources)
    except SourceError as exc:
        slot = plan.slot_files.index(Path(exc.file).name) if exc.file else 0
        if exc.code == 124:  # data overlaps program: measure the program alone
            raise _too_big(plan, slot, _overflow(plan, slot)) from None
        raise BuildError(
            f"{plan.label}: generated PBASIC does not tokenize: {exc}",
            hint="this is a bstool bug in templates/pbasic; please report it with the "
            "controller file",
        ) from None


def _overflow(plan: ModulePlan, slot: int) -> int:
    try:
        image = _tokenize_sources(render_module(plan, probe=True)).slots[slot]
    except BstoolError:  # pragma: no cover - cannot measure
        return 0
    data = len(plan.rule_slots[slot - 1]) if slot else int(image.data_bytes)
    return max(0, int(image.program_bytes) + data - SLOT_BYTES)


def check_output(
    out: Path, *, force: bool = False, protect: Sequence[str | os.PathLike[str]] = ()
) -> None:
    """Refuse to replace anything but a previous build (checked before any work): a folder is
    a build when its manifest.json says so (format bstool.build/...), not because it has one.
    A path that cannot be written (its parent a file, no permission) is refused here too."""
    if out.is_dir() and any(out.iterdir()) and not force and not buildfile.is_build(out):
        has = (
            "a manifest.json that is not a bstool build's"
            if (out / buildfile.MANIFEST_FILE).exists()
            else "no bstool build (no manifest.json)"
        )
        raise InputError(
            f"output folder {out} is not empty and holds {has}",
            hint="choose an empty or new folder with -o (bstool replaces only its own builds), "
            "or add --force to replace it",
        )
    foreign = [] if force else buildfile.foreign_files(out)
    if foreign:
        names = ", ".join(str(f.relative_to(out)) for f in foreign[:5])
        more = f" and {len(foreign) - 5} more" if len(foreign) > 5 else ""
        raise InputError(
            f"the build folder {out} holds files bstool did not write ({names}{more}); "
            "compiling replaces the folder whole and would delete them",
            hint="move them out of the build, choose another folder with -o, or add --force "
            "to delete them",
        )
    outputs.check_dir(out, "output folder", force=True, protect=tuple(protect))


def _write_atomically(
    out: Path,
    results: list[ModuleResult],
    manifest: buildfile.Manifest,
    wiring: str,
    controller: dict[str, Any],
) -> None:
    """Write everything into a fresh folder beside ``out``, then swap it in with renames."""
    with outputs.staged_dir(out) as tmp:  # swapped in whole, with the user's umask
        for res in results:
            folder = tmp / "modules" / res.plan.dirname
            folder.mkdir(parents=True)
            for name, text in res.sources.items():
                (folder / name).write_text(text, encoding="utf-8")
            for sr in res.slots:
                if sr.eeprom is not None and sr.packets is not None:
                    (folder / f"slot{sr.slot}.eeprom").write_bytes(sr.eeprom)
                    (folder / f"slot{sr.slot}.packets").write_bytes(sr.packets)
        fileio.write_text(tmp / buildfile.MANIFEST_FILE, buildfile.dumps(manifest))
        fileio.write_text(tmp / buildfile.WIRING_FILE, wiring)
        fileio.write_text(tmp / buildfile.CONTROLLER_FILE, buildfile.dumps_json(controller))
