"""The build folder (format ``bstool.build/1``): the one contract between compile, flash and twin.

``bstool compile`` writes it (:func:`dumps` of a :class:`Manifest`), ``bstool flash`` and the
twin read it (:func:`load`), nobody else touches its files. The folder::

    manifest.json              this module's Manifest, as JSON (docs/DEVELOPING.md)
    controller.json            the compiled controller (CONTROLLER_FILE)
    WIRING.md                  the harness, for people
    modules/L<i>.M<j>/         main.bsx (+ slot files), slot<N>.eeprom, slot<N>.packets

A folder is a build because its manifest says ``"format": "bstool.build/1"`` (:func:`is_build`),
not because it holds a file called manifest.json. :func:`load` checks every field (an
:class:`~bstool.errors.InputError` names the file and the field) and, with ``verify``, that each
slot image is the one the manifest's sha256 names (a :class:`~bstool.errors.BuildError`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from bstool.errors import BuildError, InputError
from bstool.moduleid import ModuleId, parse_module

FORMAT = "bstool.build/1"
FORMAT_FAMILY = "bstool.build/"
MANIFEST_FILE = "manifest.json"
CONTROLLER_FILE = "controller.json"
"""The compiled controller, copied into the build: `bstool twin BUILD` compares with it."""
WIRING_FILE = "WIRING.md"
PROGRESS_FILE = "flash-progress.json"
"""Written into a build by `bstool flash --all` (which modules are done): bstool's own too."""
SLOT_BYTES = 2048
RECOMPILE = "recompile the controller: bstool compile best.json -o BUILD"

T = TypeVar("T")


# ---- the manifest's parts ------------------------------------------------------------------


@dataclass(frozen=True)
class ControllerInfo:
    file: str  # the controller file's name when compiled
    copy: str  # its copy inside the build (CONTROLLER_FILE)
    hash: str  # full sha256 hex (bstool.controllers.controller_hash)
    hash8: str
    model: str


@dataclass(frozen=True)
class RobotSize:
    legs: int
    modules: int
    states: int


@dataclass(frozen=True)
class LinkSettings:
    """The link's serial settings and the serve loop's constants (bstool.wire.link,
    protocol/link.md §5); the SERIN waits in 0.4 ms units, each plus 0..``jitter_units``."""

    protocol: str
    baud: int
    baudmode: int
    pace_ms: int
    hold_frames: int
    listen_units: int
    reply_wait_units: int
    payload_wait_units: int
    jitter_units: int
    keepalive_rounds: int
    dead_limit_ms: int
    power_up_window_ms: int
    states_wait_units: int | None = None  # NN: StatesWait (the packed states after READY)
    pace_ticks: int | None = None  # NN: PaceTicks (silent upstream ticks before pacing)
    # CA: the silence clock (0.8 ms units): a tick, and the lower bounds each try adds
    tick_quiet_units: int | None = None  # TickQuiet
    ask_quiet_units: int | None = None  # AskQuiet: a master's try that heard nothing
    listen_quiet_units: int | None = None  # ListenQuiet: a listen that heard nothing
    heard_quiet_units: int | None = None  # HeardQuiet: a try that heard a byte
    ask_heard_quiet_units: int | None = None  # AskHeardQuiet: a master's try that heard a byte
    # CA: the hold clock (0.4 ms units: estimates of the timing model) and the tries in a row
    frame_units: int | None = None  # FrameTime: a hold frame; the hold is hold_frames of them
    master_try_units: int | None = None  # MasterTry: a master's try besides its pulse
    listen_try_units: int | None = None  # ListenTry: a listen besides its pulse
    heard_try_units: int | None = None  # HeardTry: what a listen that hears a REQ adds
    ask_tries: int | None = None  # AskTries: REQs in a row while the slave's state is missing
    lack_tries: int | None = None  # LackTries: listens in a row while the master's is missing


_LINK_OPTIONAL = (  # NN only / CA only: None (null) in a build of the other family
    "states_wait_units",
    "pace_ticks",
    "tick_quiet_units",
    "ask_quiet_units",
    "listen_quiet_units",
    "heard_quiet_units",
    "ask_heard_quiet_units",
    "frame_units",
    "master_try_units",
    "listen_try_units",
    "heard_try_units",
    "ask_tries",
    "lack_tries",
)


@dataclass(frozen=True)
class Slot:
    """One program slot of a module; the image fields are None in a sources-only build."""

    slot: int
    file: str  # the PBASIC source, relative to the build folder
    source_sha256: str
    program_bytes: int | None = None
    data_bytes: int | None = None
    eeprom: str | None = None  # slot<N>.eeprom, relative to the build folder
    packets: str | None = None  # slot<N>.packets (the download records)
    sha256: str | None = None  # of the 2048-byte image

    @property
    def has_image(self) -> bool:
        return self.eeprom is not None


@dataclass(frozen=True)
class Pin:
    """A used I/O pin. Only ``use == "link"`` pins carry the link fields."""

    pin: int
    use: str  # servo | link
    port: str | None = None  # prev | next | lead | bypass_next ... (compile.topology)
    neighbour: ModuleId | None = None
    neighbour_pin: int | None = None
    role: str | None = None  # master | slave
    colour: int | None = None
    bypass: bool = False
    send_states: int | None = None
    receive_states: int | None = None


@dataclass(frozen=True)
class ServoTable:
    pulsout: list[int]  # PULSOUT units per state 0..k-1
    clipped_states: list[int]


@dataclass(frozen=True)
class Timing:
    """The timing model's estimates for one module, in seconds (compile.plan.estimates); for
    reporting only, no constant of the programs depends on them."""

    nominal_transition_s: float  # the robot's period, unperturbed
    first_transition_s: float  # from a common power-up to the first transition
    longest_servo_gap_s: float


@dataclass(frozen=True)
class Module:
    module: ModuleId
    label: str
    dir: str
    entry: str
    initial_state: int
    slots: list[Slot]
    ram_bytes: int
    ram_bytes_available: int
    pins: list[Pin]
    servo: ServoTable
    dead_ticks: int  # DeadTicks (protocol/link.md §5)
    timing: Timing
    ram_map: dict[str, tuple[str, int]] | None = None  # "state"/"tn" -> (kind, index) in RAM

    @property
    def servo_pin(self) -> int:
        return next(p.pin for p in self.pins if p.use == "servo")

    def slot(self, number: int) -> Slot:
        for s in self.slots:
            if s.slot == number:
                return s
        have = ", ".join(str(s.slot) for s in self.slots)
        raise InputError(f"{self.label} has no slot {number} (slots: {have})")


@dataclass(frozen=True)
class Wire:
    """One link wire between two modules' pins."""

    master: ModuleId
    master_pin: int
    slave: ModuleId
    slave_pin: int
    colour: int
    bypass: bool


@dataclass(frozen=True)
class FlashStep:
    """One module of the flashing order with its slots in the order to write them."""

    module: ModuleId
    slots: list[int]


@dataclass(frozen=True)
class Manifest:
    controller: ControllerInfo
    robot: RobotSize
    period_s: float
    tokenized: bool  # False: PBASIC sources only (compile_controller(tokenize=False))
    link: LinkSettings
    announcement: str  # bstool.wire.announce.DESCRIPTION
    modules: list[Module]
    links: list[Wire]
    flash_order: list[FlashStep]
    format: str = FORMAT
    # the robot it was compiled for (bstool.robot.robotfile.Robot.to_json: every value and the
    # uncertain ranges), when it is not the default one; written only then, as "robot_values"
    robot_values: dict[str, Any] | None = None

    def module(self, mid: ModuleId) -> Module | None:
        return next((m for m in self.modules if m.module == mid), None)


# ---- writing ------------------------------------------------------------------------------


def _slot_json(s: Slot) -> dict[str, Any]:
    out: dict[str, Any] = {
        "slot": s.slot,
        "file": s.file,
        "source_sha256": s.source_sha256,
        "program_bytes": s.program_bytes,
        "data_bytes": s.data_bytes,
    }
    if s.eeprom is not None:
        out.update(eeprom=s.eeprom, packets=s.packets, sha256=s.sha256)
    return out


def _pin_json(p: Pin) -> dict[str, Any]:
    out: dict[str, Any] = {"pin": p.pin, "use": p.use}
    if p.use != "link":
        return out
    out.update(
        port=p.port,
        neighbour=str(p.neighbour),
        neighbour_pin=p.neighbour_pin,
        role=p.role,
        colour=p.colour,
    )
    if p.bypass:
        out["bypass"] = True
    out.update(send_states=p.send_states, receive_states=p.receive_states)
    return out


def _module_json(m: Module) -> dict[str, Any]:
    out: dict[str, Any] = {
        "module": str(m.module),
        "label": m.label,
        "dir": m.dir,
        "entry": m.entry,
        "initial_state": m.initial_state,
        "slots": [_slot_json(s) for s in m.slots],
        "ram_bytes": m.ram_bytes,
        "ram_bytes_available": m.ram_bytes_available,
        "pins": [_pin_json(p) for p in m.pins],
        "servo": {"pulsout": list(m.servo.pulsout), "clipped_states": list(m.servo.clipped_states)},
        "dead_ticks": m.dead_ticks,
        "timing": dict(m.timing.__dict__),
    }
    if m.ram_map:
        out["ram_map"] = {k: [kind, index] for k, (kind, index) in m.ram_map.items()}
    return out


def to_json(man: Manifest) -> dict[str, Any]:
    """The manifest as the JSON object on disk (field order as written)."""
    out: dict[str, Any] = {
        "format": man.format,
        "controller": dict(man.controller.__dict__),
        "robot": dict(man.robot.__dict__),
    }
    if man.robot_values is not None:
        out["robot_values"] = man.robot_values
    return out | {
        "period_s": man.period_s,
        "tokenized": man.tokenized,
        "link": dict(man.link.__dict__),
        "announcement": man.announcement,
        "modules": [_module_json(m) for m in man.modules],
        "links": [
            {
                "master": str(w.master),
                "master_pin": w.master_pin,
                "slave": str(w.slave),
                "slave_pin": w.slave_pin,
                "colour": w.colour,
                "bypass": w.bypass,
            }
            for w in man.links
        ],
        "flash_order": [{"module": str(s.module), "slots": list(s.slots)} for s in man.flash_order],
    }


_SCALAR_LIST = re.compile(r"\[\s*([^\[\]{}]*?)\s*\]", re.S)


def dumps_json(obj: Any) -> str:
    """JSON with one field per line but lists of numbers on one line (short, diff-friendly)."""
    text = json.dumps(obj, indent=1)
    return (
        _SCALAR_LIST.sub(lambda mt: "[" + re.sub(r"\s*\n\s*", " ", mt.group(1)) + "]", text) + "\n"
    )


def dumps(man: Manifest) -> str:
    """manifest.json's text."""
    return dumps_json(to_json(man))


# ---- reading ------------------------------------------------------------------------------


class _Fields:
    """A JSON object being read: every access names the file and the field path on error."""

    def __init__(self, obj: Any, file: Path, where: str) -> None:
        if not isinstance(obj, dict):
            raise self._error(file, where, "an object", obj)
        self.obj, self.file, self.where = obj, file, where

    @staticmethod
    def _error(file: Path, where: str, want: str, got: Any) -> InputError:
        kind = "nothing" if got is _MISSING else f"{type(got).__name__} {json.dumps(got)[:40]}"
        return InputError(
            f"{file}: {where or 'the manifest'}: expected {want}, got {kind}",
            hint=f"the build is damaged or from another bstool version; {RECOMPILE}",
        )

    def _path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def get(self, key: str, kind: type[T], want: str, *, optional: bool = False) -> T:
        value = self.obj.get(key, _MISSING)
        if optional and (value is _MISSING or value is None):
            return None  # type: ignore[return-value]  # callers ask for T | None
        ok = isinstance(value, kind) and not (kind is int and isinstance(value, bool))
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value, ok = float(value), True
        if not ok:
            raise self._error(self.file, self._path(key), want, value)
        return value

    def integer(self, key: str, *, optional: bool = False) -> Any:
        return self.get(key, int, "an integer", optional=optional)

    def number(self, key: str) -> float:
        return self.get(key, float, "a number")

    def string(self, key: str, *, optional: bool = False) -> Any:
        return self.get(key, str, "a string", optional=optional)

    def boolean(self, key: str, *, default: bool | None = None) -> bool:
        if default is not None and key not in self.obj:
            return default
        return self.get(key, bool, "true or false")

    def ints(self, key: str) -> list[int]:
        values = self.get(key, list, "a list of integers")
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise self._error(self.file, self._path(key), "a list of integers", values)
        return list(values)

    def module_id(self, key: str, robot: RobotSize | None) -> ModuleId:
        text = self.string(key)
        try:
            if robot is None:
                return parse_module(text)
            return parse_module(text, robot.legs, robot.modules)
        except InputError as exc:
            raise InputError(
                f"{self.file}: {self._path(key)}: {exc.message}", hint=RECOMPILE
            ) from None

    def sub(self, key: str) -> _Fields:
        return _Fields(self.obj.get(key, _MISSING), self.file, self._path(key))

    def items(self, key: str) -> Iterator[_Fields]:
        values = self.get(key, list, "a list")
        for n, value in enumerate(values):
            yield _Fields(value, self.file, f"{self._path(key)}[{n}]")


_MISSING: Any = object()


def _read_slot(f: _Fields) -> Slot:
    return Slot(
        slot=f.integer("slot"),
        file=f.string("file"),
        source_sha256=f.string("source_sha256"),
        program_bytes=f.integer("program_bytes", optional=True),
        data_bytes=f.integer("data_bytes", optional=True),
        eeprom=f.string("eeprom", optional=True),
        packets=f.string("packets", optional=True),
        sha256=f.string("sha256", optional=True),
    )


def _read_pin(f: _Fields, robot: RobotSize) -> Pin:
    pin, use = f.integer("pin"), f.string("use")
    if use != "link":
        return Pin(pin, use)
    return Pin(
        pin=pin,
        use=use,
        port=f.string("port"),
        neighbour=f.module_id("neighbour", robot),
        neighbour_pin=f.integer("neighbour_pin"),
        role=f.string("role"),
        colour=f.integer("colour"),
        bypass=f.boolean("bypass", default=False),
        send_states=f.integer("send_states"),
        receive_states=f.integer("receive_states"),
    )


def _read_ram_map(f: _Fields) -> dict[str, tuple[str, int]] | None:
    raw = f.obj.get("ram_map")
    if raw is None:
        return None
    out: dict[str, tuple[str, int]] = {}
    ram = f.sub("ram_map")
    for name, spec in ram.obj.items():
        ok = (
            isinstance(spec, list)
            and len(spec) == 2
            and spec[0] in ("bit", "nib", "byte", "word")
            and isinstance(spec[1], int)
        )
        if not ok:
            raise _Fields._error(
                f.file, f"{ram.where}.{name}", '["bit|nib|byte|word", index]', spec
            )
        out[str(name)] = (str(spec[0]), int(spec[1]))
    return out


def _read_module(f: _Fields, robot: RobotSize) -> Module:
    servo, timing = f.sub("servo"), f.sub("timing")
    return Module(
        module=f.module_id("module", robot),
        label=f.string("label"),
        dir=f.string("dir"),
        entry=f.string("entry"),
        initial_state=f.integer("initial_state"),
        slots=[_read_slot(s) for s in f.items("slots")],
        ram_bytes=f.integer("ram_bytes"),
        ram_bytes_available=f.integer("ram_bytes_available"),
        pins=[_read_pin(p, robot) for p in f.items("pins")],
        servo=ServoTable(servo.ints("pulsout"), servo.ints("clipped_states")),
        dead_ticks=f.integer("dead_ticks"),
        timing=Timing(**{name: timing.number(name) for name in Timing.__dataclass_fields__}),
        ram_map=_read_ram_map(f),
    )


def _fields_of(cls: Callable[..., T], f: _Fields, kinds: dict[str, str]) -> T:
    read = {"int": f.integer, "str": f.string}
    return cls(**{name: read[kind](name) for name, kind in kinds.items()})


def from_json(obj: Any, file: str | os.PathLike[str] = MANIFEST_FILE) -> Manifest:
    """Check and convert a parsed manifest.json; errors name ``file`` and the field."""
    path = Path(file)
    top = _Fields(obj, path, "")
    fmt = obj.get("format")
    if fmt != FORMAT:
        raise InputError(
            f"{path}: expected format {FORMAT}, got {fmt!r}",
            hint="not a bstool build, or from another bstool version: "
            + RECOMPILE
            + (" (this bstool reads bstool.build/1)" if str(fmt).startswith(FORMAT_FAMILY) else ""),
        )
    robot = _fields_of(
        RobotSize, top.sub("robot"), {"legs": "int", "modules": "int", "states": "int"}
    )
    controller = _fields_of(
        ControllerInfo,
        top.sub("controller"),
        {k: "str" for k in ("file", "copy", "hash", "hash8", "model")},
    )
    link = top.sub("link")
    link_settings = LinkSettings(
        protocol=link.string("protocol"),
        **{
            k: link.integer(k, optional=k in _LINK_OPTIONAL)
            for k in LinkSettings.__dataclass_fields__
            if k != "protocol"
        },
    )
    wires = [
        Wire(
            master=w.module_id("master", robot),
            master_pin=w.integer("master_pin"),
            slave=w.module_id("slave", robot),
            slave_pin=w.integer("slave_pin"),
            colour=w.integer("colour"),
            bypass=w.boolean("bypass"),
        )
        for w in top.items("links")
    ]
    order = [
        FlashStep(s.module_id("module", robot), s.ints("slots")) for s in top.items("flash_order")
    ]
    modules = [_read_module(m, robot) for m in top.items("modules")]
    period = top.number("period_s")
    if not period > 0:
        raise _Fields._error(path, "period_s", "a period > 0 seconds", period)
    values = obj.get("robot_values")
    if values is not None and not isinstance(values, dict):
        raise _Fields._error(path, "robot_values", "an object (the robot's values)", values)
    return Manifest(
        controller=controller,
        robot=robot,
        period_s=period,
        tokenized=top.boolean("tokenized"),
        link=link_settings,
        announcement=top.string("announcement"),
        modules=modules,
        links=wires,
        flash_order=order,
        robot_values=values,
    )


# ---- a build folder -----------------------------------------------------------------------


@dataclass
class Build:
    """A loaded build folder: its root and manifest, and the slot images it holds."""

    root: Path
    manifest: Manifest
    _images: dict[tuple[ModuleId, int], bytes] = field(default_factory=dict, repr=False)

    @property
    def legs(self) -> int:
        return self.manifest.robot.legs

    @property
    def modules(self) -> int:
        return self.manifest.robot.modules

    @property
    def period(self) -> float:
        return self.manifest.period_s

    @property
    def controller_hash(self) -> str:
        return self.manifest.controller.hash

    @property
    def controller_file(self) -> Path:
        return self.root / self.manifest.controller.copy

    def path(self, relative: str) -> Path:
        """A file the manifest names (paths in it are relative to the build folder)."""
        return self.root / relative

    def module(self, mid: ModuleId) -> Module:
        found = self.manifest.module(mid)
        if found is None:
            raise InputError(
                f"module {mid.label} is not in the build {self.root}",
                hint="its modules: " + ", ".join(str(m.module) for m in self.manifest.modules),
            )
        return found

    def require_images(self) -> None:
        """Refuse a sources-only build (compiled with ``tokenize=False``)."""
        if not self.manifest.tokenized:
            raise BuildError(
                f"the build {self.root} holds PBASIC sources only (no slot images)",
                hint=RECOMPILE,
            )

    def image(self, mid: ModuleId, slot: Slot) -> bytes:
        """The 2048-byte image of ``slot`` of module ``mid``, checked against its sha256."""
        key = (mid, slot.slot)
        if key in self._images:
            return self._images[key]
        if slot.eeprom is None:
            raise BuildError(
                f"{self.root}: module {mid} slot {slot.slot} has no image (PBASIC sources only)",
                hint=RECOMPILE,
            )
        path = self.path(slot.eeprom)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise BuildError(f"cannot read {path}: {exc.strerror or exc}", hint=RECOMPILE) from None
        if len(data) != SLOT_BYTES:
            raise BuildError(
                f"{path}: {len(data)} bytes, a slot image has {SLOT_BYTES}", hint=RECOMPILE
            )
        if slot.sha256 is None or hashlib.sha256(data).hexdigest() != slot.sha256.lower():
            raise BuildError(
                f"{path} differs from the manifest's sha256: the build was changed",
                hint=RECOMPILE,
            )
        self._images[key] = data
        return data

    def images(self, mid: ModuleId) -> dict[int, bytes]:
        """Slot number → 2048-byte image of a module (each checked against the manifest)."""
        return {s.slot: self.image(mid, s) for s in self.module(mid).slots}

    def verify(self) -> None:
        """Check every slot image against the manifest's sha256 (a changed build is refused)."""
        self.require_images()
        for m in self.manifest.modules:
            self.images(m.module)


def _read_manifest(root: Path) -> Any:
    path = root / MANIFEST_FILE
    if not root.is_dir():
        raise InputError(
            f"{root} is not a bstool build (no such folder, so no manifest.json)",
            hint="run `bstool compile best.json -o BUILD` first",
        )
    if not path.is_file():
        raise InputError(
            f"{root} is not a bstool build (no manifest.json)",
            hint="run `bstool compile best.json -o BUILD` first",
        )
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}:{exc.lineno}:{exc.colno}: malformed JSON: {exc.msg}", hint=RECOMPILE
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from None


def load(path: str | os.PathLike[str], *, verify: bool = True) -> Build:
    """Read the build folder ``path``; with ``verify``, also check it holds slot images and
    that each is the one the manifest's sha256 names (what flash and the twin need)."""
    root = Path(path)
    build = Build(root, from_json(_read_manifest(root), root / MANIFEST_FILE))
    if verify:
        build.verify()
    return build


def is_build(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a folder holding a bstool build (its manifest's ``format``)."""
    man = Path(path) / MANIFEST_FILE
    try:
        obj = json.loads(man.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(obj, dict) and str(obj.get("format", "")).startswith(FORMAT_FAMILY)


def foreign_files(path: str | os.PathLike[str]) -> list[Path]:
    """Files in the build folder ``path`` that bstool did not write (a user's notes, say): not
    the manifest, WIRING.md, controller.json, the flash progress file, or a file the manifest
    names. Empty for a folder that is not a readable build."""
    root = Path(path)
    try:
        manifest = from_json(_read_manifest(root), root / MANIFEST_FILE)
    except (InputError, BuildError):
        return []
    own = {root / name for name in (MANIFEST_FILE, CONTROLLER_FILE, WIRING_FILE, PROGRESS_FILE)}
    for module in manifest.modules:
        for slot in module.slots:
            own.update(root / f for f in (slot.file, slot.eeprom, slot.packets) if f is not None)
    return sorted(p for p in root.rglob("*") if not p.is_dir() and p not in own)
