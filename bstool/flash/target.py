"""What to flash: a compile output directory, a .bsx program or a controller file.

All three become a list of :class:`ModulePlan` (module, slots with their records, expected
controller hash). A build is read with :func:`bstool.buildfile.load` (the one reader of the
format) and each slot image is checked against the manifest's sha256.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bstool import buildfile, fileio
from bstool.errors import BuildError, InputError
from bstool.moduleid import ModuleId, parse_module
from bstool.tokenizer import tokenize_file
from bstool.wire import programming as P


@dataclass
class SlotPlan:
    slot: int
    records: list[bytes]
    image: bytes | None = None  # the full 2048-byte image when known

    @property
    def n_bytes(self) -> int:
        return len(self.records) * P.RECORD_SIZE


@dataclass
class ModulePlan:
    module: ModuleId | None
    slots: list[SlotPlan]
    controller_hash: str | None = None  # full hex; messages show 8 digits

    @property
    def label(self) -> str:
        return self.module.label if self.module else "stamp"


@dataclass
class Target:
    modules: list[ModulePlan]  # in flashing order
    build_dir: Path | None = None
    controller_hash: str | None = None
    keep: list[Any] = field(default_factory=list)  # temporary directories kept alive


def parse_packets(data: bytes, where: str) -> list[bytes]:
    """Records from a ``.packets`` file: binary 18-byte records, or the same as hex text."""
    text = data.strip()
    if text and all(c in b"0123456789abcdefABCDEF \t\r\n" for c in text):
        try:
            data = bytes.fromhex(text.decode("ascii"))
        except ValueError:
            raise BuildError(f"{where}: not a file of 18-byte download records") from None
    if len(data) % P.RECORD_SIZE != 0:
        raise BuildError(
            f"{where}: {len(data)} bytes is not a whole number of 18-byte records",
            hint="recompile: bstool compile",
        )
    records = [data[i : i + P.RECORD_SIZE] for i in range(0, len(data), P.RECORD_SIZE)]
    for n, rec in enumerate(records):
        if not P.record_ok(rec):
            raise BuildError(
                f"{where}: record {n + 1} is damaged (bad length, header or checksum)",
                hint="recompile: bstool compile",
            )
    return records


#: builds a controller file into a build folder: ``compiler(controller, out, modules=[...])``
#: (``bstool.compile.compile_controller``; flash sits beside compile, so its caller hands it)
Compiler = Callable[..., object]


def load_target(
    path: str | Path,
    *,
    module: str | None = None,
    slot: int | None = None,
    every_module: bool = False,
    compiler: Compiler | None = None,
) -> Target:
    """Resolve TARGET into module plans; ``module``/``slot`` narrow it down. A controller file
    is compiled first with ``compiler`` (without one it is refused: compile it first)."""
    p = Path(path)
    if not p.exists():
        raise InputError(
            f"flash target not found: {p}", hint="give a build directory, a .bsx or a .json"
        )
    if p.is_dir():
        target = _from_build(p, module, every_module)
    elif p.suffix.lower() == ".bsx":
        if every_module:
            raise InputError("--all needs a build directory, not a .bsx file")
        target = _from_bsx(p, module)
    else:
        target = _from_controller(p, module, every_module, compiler)
    if slot is not None:
        for plan in target.modules:
            chosen = [s for s in plan.slots if s.slot == slot]
            if not chosen:
                have = ", ".join(str(s.slot) for s in plan.slots)
                raise InputError(f"{plan.label} has no slot {slot} (slots: {have})")
            plan.slots = chosen
    return target


def _read_slot(build: buildfile.Build, mid: ModuleId, slot: buildfile.Slot) -> SlotPlan:
    image = build.image(mid, slot)  # checked against the manifest's sha256
    if slot.packets is None:
        return SlotPlan(slot.slot, P.records_for_image(image), image)
    packets = build.path(slot.packets)
    try:
        data = packets.read_bytes()
    except OSError as exc:
        raise BuildError(
            f"cannot read {packets}: {exc.strerror or exc}", hint=buildfile.RECOMPILE
        ) from None
    records = parse_packets(data, str(packets))
    for rec in records:
        b = P.record_block(rec)
        if rec[1:17] != image[b * P.BLOCK_SIZE : (b + 1) * P.BLOCK_SIZE]:
            raise BuildError(
                f"{packets} does not match {Path(slot.eeprom or '').name} at block {b}",
                hint=buildfile.RECOMPILE,
            )
    return SlotPlan(slot.slot, records, image)


def _from_build(d: Path, module: str | None, every_module: bool) -> Target:
    build = buildfile.load(d, verify=False)  # each image is checked as it is read below
    build.require_images()
    man = build.manifest
    order = man.flash_order or [buildfile.FlashStep(m.module, []) for m in man.modules]
    if module is not None:
        wanted = parse_module(module)
        build.module(wanted)  # not in the build: an InputError listing its modules
        order = [o for o in order if o.module == wanted] or [buildfile.FlashStep(wanted, [])]
    elif not every_module and len(order) != 1:
        raise InputError(
            f"the build {d} has {len(order)} modules: choose one",
            hint="add --module L.M (e.g. --module 0.0), or --all to walk every module",
        )
    chash = build.controller_hash.lower()
    plans = []
    for step in order:
        entry = build.module(step.module)
        slots = [_read_slot(build, step.module, s) for s in entry.slots]
        if not slots:
            raise BuildError(f"{d}: no slot images for {step.module.label}", hint="recompile")
        # the manifest's order when given, else other slots first and slot 0 last: slot 0
        # starts running after each session, so it should be the complete program
        rank = {n: i for i, n in enumerate(step.slots)}
        slots.sort(key=lambda sp: (rank.get(sp.slot, len(rank)), sp.slot == 0, sp.slot))
        plans.append(ModulePlan(step.module, slots, chash))
    return Target(plans, d, chash)


def _from_bsx(path: Path, module: str | None) -> Target:
    project = tokenize_file(path)
    items = sorted(project.slots.items())
    slots = [SlotPlan(n, list(img.records), bytes(img.eeprom)) for n, img in items]
    mid = parse_module(module) if module else None
    return Target([ModulePlan(mid, slots)])


def _from_controller(
    path: Path, module: str | None, every_module: bool, compiler: Compiler | None
) -> Target:
    obj = fileio.read_json(path, "controller file")
    if not (isinstance(obj, dict) and str(obj.get("format", "")).startswith("bstool.controller")):
        raise InputError(
            f"{path}: not a build directory, a .bsx file or a controller file",
            hint="flash the output of bstool compile, a .bsx program or a best.json",
        )
    size = (obj.get("legs"), obj.get("modules"))
    if module is None and not every_module and size != (1, 1):  # said before compiling
        raise InputError(
            f"the controller {path} compiles to one program per module: choose one",
            hint="add --module L.M (e.g. --module 0.0), or compile it and flash the build "
            "with --all",
        )
    if compiler is None:
        raise InputError(
            f"{path} is a controller file: compile it first",
            hint=f"bstool compile {path} -o build/, then flash build/",
        )
    tmp = tempfile.TemporaryDirectory(prefix="bstool-flash-")
    build = Path(tmp.name) / "build"
    compiler(path, build, modules=[module] if module and not every_module else [])
    target = _from_build(build, module, every_module)
    target.keep.append(tmp)
    return target
