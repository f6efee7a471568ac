"""Flashing whole modules: sessions per slot, the start-up check, and ``--all`` walks.

Library API (no printing, no exit): :func:`flash_module` and :func:`flash_all` report
through callbacks and raise :class:`bstool.errors.DeviceError` subclasses.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import serial

from bstool import buildfile, fileio
from bstool.errors import DeviceError, InputError
from bstool.flash.errors import AnnouncementError, FlashInterrupted, PortError
from bstool.flash.port import open_port
from bstool.flash.session import Programmer, Progress, SlotResult, Timing
from bstool.flash.target import ModulePlan, Target
from bstool.moduleid import ModuleId, parse_module
from bstool.wire import programming as P

PROGRESS_FILE = buildfile.PROGRESS_FILE
PROGRESS_FORMAT = "bstool.flash-progress/1"


@dataclass
class ModuleReport:
    label: str
    port: str
    slots: list[SlotResult] = field(default_factory=list)
    announcement: tuple[int, int, str] | None = None
    announcement_ok: bool | None = None  # None: nothing expected or nothing heard
    version: str | None = None

    @property
    def bytes_sent(self) -> int:
        return sum(s.bytes_sent for s in self.slots)

    @property
    def records(self) -> int:
        return sum(s.records for s in self.slots)

    @property
    def seconds(self) -> float:
        return sum(s.seconds for s in self.slots)

    def summary(self, baud: int = P.BAUD) -> str:
        """``2307 B in 128 records, 2.55 s, 904 B/s = 94% of the 9600-baud limit (960 B/s)``."""
        limit = baud / P.BITS_PER_BYTE
        rate = self.bytes_sent / self.seconds if self.seconds > 0 else float("inf")
        pct = f"{100 * rate / limit:.0f}%" if self.seconds > 0 else "-"
        return (
            f"{self.bytes_sent} B in {self.records} record{'' if self.records == 1 else 's'}, "
            f"{self.seconds:.2f} s, "
            f"{rate:.0f} B/s = {pct} of the {baud}-baud limit ({limit:.0f} B/s)"
        )


def _check_announcement(plan: ModulePlan, heard: tuple[int, int, str] | None) -> bool | None:
    if heard is None:
        return None
    leg, mod, h8 = heard
    problems = []
    if plan.module is not None and (leg, mod) != tuple(plan.module):
        problems.append(f"module L{leg}.M{mod}")
    if plan.controller_hash and h8 != plan.controller_hash[:8]:
        problems.append(f"controller {h8}")
    if problems:
        want = f"{plan.label} {plan.controller_hash[:8] if plan.controller_hash else ''}".strip()
        raise AnnouncementError(
            f"{plan.label} was flashed but the program announces {' and '.join(problems)} "
            f"(expected {want})",
            hint="wrong cable or a stale build: check which module is on this port",
        )
    return plan.module is not None or plan.controller_hash is not None


def flash_module(
    port: str | serial.Serial,
    plan: ModulePlan,
    *,
    baud: int = P.BAUD,
    timing: Timing | None = None,
    log: Callable[[str], None] | None = None,
    trace: Callable[[str], None] | None = None,
    progress: Callable[[Progress], None] | None = None,
    on_slot_start: Callable[[int, int], None] | None = None,
    listen: bool = True,
) -> ModuleReport:
    """Upload every slot of ``plan`` (one session each), then check the start-up line."""
    timing = timing or Timing()
    ser = open_port(port, baud=baud, timeout=timing.reply) if isinstance(port, str) else port
    name = port if isinstance(port, str) else str(ser.port)
    report = ModuleReport(plan.label, name)
    prog = Programmer(ser, name=name, timing=timing, log=log, trace=trace)
    current: int | None = None
    try:
        for sp in plan.slots:
            current = sp.slot
            if on_slot_start:
                on_slot_start(sp.slot, len(sp.records))
            report.slots.append(prog.upload_slot(sp.slot, sp.records, progress))
            current = None
        report.version = prog.version
        if listen:
            heard = prog.listen()
            if heard is None and prog.reset_to_run():
                heard = prog.listen()
            report.announcement = heard
            report.announcement_ok = _check_announcement(plan, heard)
    except (OSError, serial.SerialException) as exc:  # unplugged adapter, port gone
        where = f"{plan.label} slot {current}" if current is not None else plan.label
        raise PortError(
            f"the port {name} failed while flashing {where} ({exc}); it may be incomplete",
            hint="check the USB cable/adapter, then run the same command again",
        ) from None
    except KeyboardInterrupt:
        where = f"{plan.label} slot {current}" if current is not None else plan.label
        raise FlashInterrupted(
            f"interrupted: {where} on {name} may be incomplete",
            hint="run the same command again to flash it completely",
        ) from None
    finally:
        if isinstance(port, str):
            ser.close()
    return report


# -- --all ----------------------------------------------------------------------------------
@dataclass
class WalkResult:
    status: dict[str, str]  # label -> flashed / failed / skipped / flashed earlier
    messages: dict[str, str]
    reports: dict[str, ModuleReport]

    @property
    def failed(self) -> list[str]:
        return [k for k, v in self.status.items() if v == "failed"]


def _load_progress(build_dir: Path | None, chash: str | None) -> dict[str, Any]:
    if build_dir is None or not (build_dir / PROGRESS_FILE).exists():
        return {}
    data = fileio.read_json(build_dir / PROGRESS_FILE, "flash progress file")
    if not isinstance(data, dict) or data.get("controller_hash") != chash:
        return {}  # another build: start over
    modules = data.get("modules", {})
    return modules if isinstance(modules, dict) else {}


def _save_progress(build_dir: Path | None, chash: str | None, modules: dict[str, Any]) -> None:
    if build_dir is not None:
        fileio.write_json(
            build_dir / PROGRESS_FILE,
            {"format": PROGRESS_FORMAT, "controller_hash": chash, "modules": modules},
        )


def read_ports_file(path: str | Path) -> dict[ModuleId, str]:
    """``{"L0.M0": "/dev/ttyUSB0", "1.2": "bstwin://L1.M2", ...}`` -> module -> port."""
    data = fileio.read_json(path, "ports file")
    if not isinstance(data, dict) or not all(isinstance(v, str) for v in data.values()):
        raise InputError(
            f"{path}: expected a JSON object module -> port", hint='e.g. {"L0.M0": "/dev/ttyUSB0"}'
        )
    return {parse_module(k): v for k, v in data.items()}


def check_module(
    port: str | serial.Serial,
    plan: ModulePlan,
    *,
    baud: int = P.BAUD,
    timing: Timing | None = None,
) -> str | None:
    """Whether the stamp on ``port`` runs ``plan``: None if its start-up announcement names
    the plan's module and controller, else what was heard instead (a reason to re-flash)."""
    if plan.module is None or not plan.controller_hash:
        return "the build names no module and controller to check the stamp against"
    timing = timing or Timing()
    want = f"{plan.label} {plan.controller_hash[:8]}"
    try:
        ser = open_port(port, baud=baud, timeout=timing.reply) if isinstance(port, str) else port
    except DeviceError as exc:
        return f"its port cannot be opened ({exc.message})"
    try:
        prog = Programmer(ser, name=port if isinstance(port, str) else str(ser.port), timing=timing)
        prog.reset_to_run()  # restart the program: it announces itself first
        heard = prog.listen()
    except (OSError, serial.SerialException) as exc:
        return f"its port failed ({exc})"
    finally:
        if isinstance(port, str):
            ser.close()
    if heard is None:
        return f"the stamp does not announce {want} (nothing heard)"
    leg, mod, h8 = heard
    if (leg, mod) != tuple(plan.module) or h8 != plan.controller_hash[:8]:
        return f"the stamp announces L{leg}.M{mod} {h8}, not {want}"
    return None


def flash_all(
    target: Target,
    *,
    port_for: Callable[[ModulePlan], str | None],
    flash: Callable[[str, ModulePlan], ModuleReport],
    log: Callable[[str], None] | None = None,
    check: Callable[[str, ModulePlan], str | None] | None = None,
    force: bool = False,
) -> WalkResult:
    """Walk the modules in flashing order, resuming after those already flashed.

    ``port_for`` returns the port for a module (it may prompt) or None to skip it; raise
    :class:`KeyboardInterrupt` or return ``"quit"`` to stop. Progress goes to the build dir.

    The progress file alone is never trusted: a module it calls flashed is skipped only if
    ``check(port, plan)`` confirms the stamp runs it (returns None); otherwise (no ``check``,
    another stamp on the cable, a fresh stamp) it is flashed again, saying why. ``force``
    ignores the progress file.
    """
    log = log or (lambda _m: None)
    saved = {} if force else _load_progress(target.build_dir, target.controller_hash)
    result = WalkResult({}, {}, {})
    for plan in target.modules:
        label = plan.label
        earlier = saved.get(label, {}).get("status") == "flashed"
        port = port_for(plan)
        if port == "quit":
            break
        if port is None:
            result.status[label] = "skipped"
            if not earlier:  # a skip does not forget a flash
                saved[label] = {"status": "skipped"}
                _save_progress(target.build_dir, target.controller_hash, saved)
            continue
        if earlier:
            why = check(port, plan) if check else "the stamp cannot be checked (not listening)"
            if why is None:
                result.status[label] = "flashed earlier"
                result.messages[label] = "(checked: its program announces itself)"
                continue
            log(f"{label}: {PROGRESS_FILE} says flashed, but {why}: flashing it again")
        saved[label] = {"status": "incomplete", "port": port, "time": time.time()}
        _save_progress(target.build_dir, target.controller_hash, saved)
        try:
            report = flash(port, plan)
        except FlashInterrupted:
            raise
        except DeviceError as exc:
            result.status[label] = "failed"
            result.messages[label] = exc.message
            saved[label] = {"status": "failed", "port": port, "message": exc.message}
            log(f"{label}: FAILED: {exc.message}")
        else:
            result.status[label] = "flashed"
            result.reports[label] = report
            saved[label] = {"status": "flashed", "port": port, "time": time.time()}
        _save_progress(target.build_dir, target.controller_hash, saved)
    return result
