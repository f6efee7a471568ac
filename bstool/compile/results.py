"""What compiling one module produced (sources, slot images, RAM, timing), before it is written."""

from __future__ import annotations

from dataclasses import dataclass

from bstool.compile.plan import ModulePlan


@dataclass
class SlotResult:
    slot: int
    file: str
    source_sha256: str
    program_bytes: int | None = None
    data_bytes: int | None = None
    eeprom: bytes | None = None
    packets: bytes | None = None


@dataclass
class ModuleResult:
    plan: ModulePlan
    sources: dict[str, str]
    slots: list[SlotResult]
    ram_bytes: int
    timing: dict[str, float]
    ram_map: dict[str, tuple[str, int]] | None = None  # STATE/TN location (twin's state probe)
