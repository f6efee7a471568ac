"""A robot's worth of virtual stamps at ``bstwin://`` URLs, flashed through the real protocol.

``flash_fleet`` creates one programming device (with its own EEPROM) per module of a build,
uploads every module with :func:`bstool.flash.flash_all` exactly as ``bstool flash --all
--ports`` would, and returns the EEPROMs, so the robot twin then runs what was flashed.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bstool.moduleid import ModuleId
from hil_mock.eeprom import Eeprom
from hil_mock.progdevice import ProgrammingDevice
from hil_mock.runners import InterpreterRunner
from hil_mock.urlhandler import add_twin, register, remove_twin

_fleet_ids = itertools.count()


@dataclass
class Fleet:
    """The devices of one robot, by module, and their port URLs."""

    devices: dict[ModuleId, ProgrammingDevice]
    urls: dict[ModuleId, str]

    @property
    def eeproms(self) -> dict[ModuleId, Eeprom]:
        return {mid: dev.eeprom for mid, dev in self.devices.items()}

    def close(self) -> None:
        for url in self.urls.values():
            remove_twin(url.removeprefix("bstwin://"))


def make_fleet(legs: int, modules: int, name: str | None = None) -> Fleet:
    """n·m fresh devices named ``<name>-L<i>.M<j>`` (erased EEPROMs, interpreter runners)."""
    register()
    prefix = name or f"fleet{next(_fleet_ids)}"
    devices, urls = {}, {}
    for i in range(legs):
        for j in range(modules):
            mid = ModuleId(i, j)
            dev_name = f"{prefix}-{mid.label}"
            devices[mid] = add_twin(
                dev_name, ProgrammingDevice(Eeprom(), runner=InterpreterRunner())
            )
            urls[mid] = f"bstwin://{dev_name}"
    return Fleet(devices, urls)


def flash_fleet(
    build_dir: str | Path, fleet: Fleet, log: Callable[[str], None] | None = None
) -> dict[str, str]:
    """Flash every module of ``build_dir`` into its device of ``fleet`` through the programming
    protocol; returns module label → status (flashed / failed ...)."""
    from bstool.flash import FAST, ModulePlan, ModuleReport, flash_all, flash_module, load_target
    from bstool.flash.flasher import PROGRESS_FILE

    # a fresh fleet has erased EEPROMs: progress of an earlier walk over this build is void
    (Path(build_dir) / PROGRESS_FILE).unlink(missing_ok=True)
    target = load_target(str(build_dir), every_module=True)

    def port_for(plan: ModulePlan) -> str | None:
        return fleet.urls[plan.module] if plan.module is not None else None

    def flash(port: str, plan: ModulePlan) -> ModuleReport:
        return flash_module(port, plan, timing=FAST)

    result = flash_all(target, port_for=port_for, flash=flash, log=log)
    return dict(result.status)
