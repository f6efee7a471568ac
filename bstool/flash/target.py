"""What to flash: a compile output directory, a .bsx program or a controller file.

All three become a list of :class:`ModulePlan` (module, slots with their records, expected
controller hash). The build layout is the one in docs/DEVELOPING.md; the manifest is read
tolerantly (see docs/flash.md) and each slot image is checked against its sha256.
"""

from __future__ import annotations

import hashlib
import importlib.util
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bstool import fileio
from bstool.errors import BuildError, InputError
from bstool.flash import protocol as P
from bstool.moduleid import ModuleId, parse_module


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


def load_target(
    path: str | Path,
    *,
    module: str | None = None,
    slot: int | None = None,
    every_module: bool = False,
) -> Target:
    """Resolve TARGET into module plans; ``module``/``slot`` narrow it down."""
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
        target = _from_controller(p, module, every_module)
    if slot is not None:
        for plan in target.modules:
            chosen = [s for s in plan.slots if s.slot == slot]
            if not chosen:
                have = ", ".join(str(s.slot) for s in plan.slots)
                raise InputError(f"{plan.label} has no slot {slot} (slots: {have})")
            plan.slots = chosen
    return target


def _module_key(entry: Any, key: str) -> str:
    if isinstance(entry, dict):
        for k in ("module", "id", "label", "name"):
            if k in entry:
                return str(entry[k])
    return key


def _manifest_modules(manifest: dict[str, Any]) -> dict[ModuleId, dict[str, Any]]:
    raw = manifest.get("modules")
    items: list[tuple[str, Any]]
    if isinstance(raw, dict):
        items = list(raw.items())
    elif isinstance(raw, list):
        items = [(_module_key(e, ""), e) for e in raw]
    else:
        raise InputError("build manifest has no 'modules'", hint="recompile: bstool compile")
    return {parse_module(_module_key(e, k)): (e if isinstance(e, dict) else {}) for k, e in items}


def _slot_entries(entry: dict[str, Any], mdir: Path) -> list[tuple[int, dict[str, Any]]]:
    slots = entry.get("slots")
    out: list[tuple[int, dict[str, Any]]] = []
    if isinstance(slots, dict):
        out = [(int(k), v if isinstance(v, dict) else {"file": v}) for k, v in slots.items()]
    elif isinstance(slots, list):
        for i, s in enumerate(slots):
            s = s if isinstance(s, dict) else {"file": s}
            out.append((int(s.get("slot", i)), s))
    else:
        for f in sorted(mdir.glob("slot*.eeprom")):
            out.append((int(f.stem[4:]), {"file": f.name}))
    return sorted(out, key=lambda t: t[0])


def _read_slot(root: Path, mdir: Path, n: int, info: dict[str, Any]) -> SlotPlan:
    if info.get("eeprom"):
        eeprom_path = root / str(info["eeprom"])
    elif str(info.get("file", "")).endswith(".eeprom"):
        eeprom_path = mdir / str(info["file"])
    else:
        eeprom_path = mdir / f"slot{n}.eeprom"
    if not eeprom_path.exists() and "eeprom" not in info and "sha256" not in info:
        raise BuildError(
            f"{mdir}: slot {n} has no EEPROM image (PBASIC sources only)",
            hint="the build was compiled without the tokenizer: recompile with bstool compile",
        )
    try:
        image = eeprom_path.read_bytes()
    except OSError as exc:
        raise BuildError(f"cannot read {eeprom_path}: {exc.strerror}", hint="recompile") from None
    if len(image) != P.SLOT_SIZE:
        raise BuildError(f"{eeprom_path}: {len(image)} bytes, a slot image has {P.SLOT_SIZE}")
    digest = info.get("sha256")
    if digest and hashlib.sha256(image).hexdigest() != str(digest).lower():
        raise BuildError(
            f"{eeprom_path} differs from the manifest's sha256: the build was changed",
            hint="recompile: bstool compile",
        )
    packets = (
        root / str(info["packets"]) if info.get("packets") else eeprom_path.with_suffix(".packets")
    )
    if packets.exists():
        records = parse_packets(packets.read_bytes(), str(packets))
        for rec in records:
            b = P.record_block(rec)
            if rec[1:17] != image[b * P.BLOCK_SIZE : (b + 1) * P.BLOCK_SIZE]:
                raise BuildError(f"{packets} does not match {eeprom_path.name} at block {b}")
    else:
        records = P.records_for_image(image)
    return SlotPlan(n, records, image)


def _flash_order(manifest: dict[str, Any]) -> list[tuple[ModuleId, list[int] | None]]:
    """``flash_order`` entries: "L.M" strings or {"module": "L.M", "slots": [...]}."""
    out: list[tuple[ModuleId, list[int] | None]] = []
    for item in manifest.get("flash_order") or []:
        if isinstance(item, dict):
            slots = item.get("slots")
            out.append(
                (parse_module(str(item.get("module"))), [int(s) for s in slots] if slots else None)
            )
        else:
            out.append((parse_module(str(item)), None))
    return out


def _controller_hash(manifest: dict[str, Any]) -> str | None:
    for key in ("controller_hash", "hash"):
        if isinstance(manifest.get(key), str):
            return str(manifest[key]).lower()
    ctrl = manifest.get("controller")
    if isinstance(ctrl, dict) and isinstance(ctrl.get("hash"), str):
        return str(ctrl["hash"]).lower()
    return None


def _from_build(d: Path, module: str | None, every_module: bool) -> Target:
    manifest = fileio.read_json(d / "manifest.json", "build manifest")
    if not isinstance(manifest, dict):
        raise InputError(f"{d / 'manifest.json'}: not a build manifest")
    if manifest.get("tokenized") is False:
        raise BuildError(
            f"the build {d} holds PBASIC sources only (compiled without the tokenizer)",
            hint="recompile with bstool compile once the tokenizer is available",
        )
    modules = _manifest_modules(manifest)
    order = _flash_order(manifest) or [(m, None) for m in modules]
    chash = _controller_hash(manifest)
    if module is not None:
        wanted = parse_module(module)
        if wanted not in modules:
            raise InputError(f"module {wanted.label} is not in the build {d}")
        order = [o for o in order if o[0] == wanted] or [(wanted, None)]
    elif not every_module and len(order) != 1:
        raise InputError(
            f"the build {d} has {len(order)} modules: choose one",
            hint="add --module L.M (e.g. --module 0.0), or --all to walk every module",
        )
    plans = []
    for mid, slot_order in order:
        entry = modules.get(mid, {})
        mdir = d / str(entry.get("dir") or f"modules/{mid.label}")
        slots = [_read_slot(d, mdir, n, info) for n, info in _slot_entries(entry, mdir)]
        if not slots:
            raise BuildError(f"{mdir}: no slot images for {mid.label}", hint="recompile")
        # the manifest's order when given, else other slots first and slot 0 last: slot 0
        # starts running after each session, so it should be the complete program
        rank = {n: i for i, n in enumerate(slot_order or [])}
        slots.sort(key=lambda sp: (rank.get(sp.slot, len(rank)), sp.slot == 0, sp.slot))
        plans.append(ModulePlan(mid, slots, chash))
    return Target(plans, d, chash)


def _from_bsx(path: Path, module: str | None) -> Target:
    try:
        from bstool.tokenizer import tokenize_file  # type: ignore[attr-defined,unused-ignore]
    except ImportError:
        raise InputError(
            f"cannot tokenize {path}: the tokenizer is not available in this bstool",
            hint="flash a compile output directory instead",
        ) from None
    project = tokenize_file(path)
    items = sorted(project.slots.items())
    slots = [SlotPlan(n, list(img.records), bytes(img.eeprom)) for n, img in items]
    mid = parse_module(module) if module else None
    return Target([ModulePlan(mid, slots)])


def _from_controller(path: Path, module: str | None, every_module: bool) -> Target:
    obj = fileio.read_json(path, "controller file")
    if not (isinstance(obj, dict) and str(obj.get("format", "")).startswith("bstool.controller")):
        raise InputError(
            f"{path}: not a build directory, a .bsx file or a controller file",
            hint="flash the output of bstool compile, a .bsx program or a best.json",
        )
    if importlib.util.find_spec("bstool.commands.compile") is None:
        raise InputError(
            f"cannot compile {path} on the fly: bstool compile is not available yet",
            hint="compile it first (bstool compile best.json -o build/) and flash build/",
        )
    from bstool.cli import cli

    tmp = tempfile.TemporaryDirectory(prefix="bstool-flash-")
    build = Path(tmp.name) / "build"
    only = ["--module", module] if module and not every_module else []
    cli.main(["compile", str(path), "-o", str(build), "--quiet", *only], standalone_mode=False)
    target = _from_build(build, module, every_module)
    target.keep.append(tmp)
    return target
