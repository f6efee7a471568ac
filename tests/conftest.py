"""Helpers shared by the tests: running the CLI, the traced controllers and their compiled
builds, and hand-made build folders in the bstool.build/1 format (written by bstool.buildfile).

The traced controllers (tests/data/traced/) are frozen copies of the controllers shipped on
2026-12-07: the link and twin tests replay fault instants traced on their programs, so they
stay on these when the shipped gaits are re-evolved. Tests of the shipped gaits themselves
(their fitness replays, bstool.builtin) read bstool/data/controllers/."""

from __future__ import annotations

import hashlib
import shutil
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import pytest

from bstool import buildfile as bf
from bstool.moduleid import ModuleId
from bstool.wire import announce
from bstool.wire import programming as P


class CliRun(NamedTuple):
    code: int
    out: str
    err: str


def run_cli(args: Sequence[str], capsys: pytest.CaptureFixture[str]) -> CliRun:
    """Run ``bstool ARGS`` in-process: its exit code and what it printed (captured)."""
    from bstool.cli import main

    code = main(list(args))
    out = capsys.readouterr()
    return CliRun(code, out.out, out.err)


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Callable[..., CliRun]:
    """``cli("states", "best.json")``: :func:`run_cli` bound to this test's capsys."""
    return lambda *args: run_cli(args, capsys)


TRACED = Path(__file__).parent / "data" / "traced"


def traced_controller(model: str) -> Path:
    """The frozen copy of the controller of ``model`` that the link tests were traced on."""
    path = TRACED / f"{model}.json"
    assert path.is_file(), f"no traced controller for {model!r}"
    return path


TracedBuild = Callable[..., Path]


@pytest.fixture(scope="session")
def traced_build(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TracedBuild]:
    """``traced_build("nnsin", period=None, fresh=False)``: the folder of ``bstool compile``
    of a traced controller, compiled once per session; ``fresh`` gives a private copy (for
    tests that write into it, e.g. flash's progress file, or damage it)."""
    from bstool.cli import main

    cache: dict[tuple[str, float | None], Path] = {}

    def get(model: str, period: float | None = None, *, fresh: bool = False) -> Path:
        key = (model, period)
        if key not in cache:
            out = tmp_path_factory.mktemp(f"{model}-{period}") / "build"
            more = ["--period", str(period)] if period is not None else []
            assert (
                main(["compile", str(traced_controller(model)), "-o", str(out), "-q", *more]) == 0
            )
            cache[key] = out
        if not fresh:
            return cache[key]
        copy = tmp_path_factory.mktemp(f"{model}-copy") / "build"
        shutil.copytree(cache[key], copy)
        return copy

    yield get


# ---- hand-made builds ------------------------------------------------------------------------


@dataclass
class FakeModule:
    """A module of a hand-made build: its slot images and what the manifest says about it."""

    module: ModuleId
    images: dict[int, bytes]
    initial_state: int = 0
    ram_map: dict[str, tuple[str, int]] | None = None
    pins: list[bf.Pin] = field(default_factory=lambda: [bf.Pin(12, "servo")])
    longest_servo_gap_s: float = 0.03
    flash_slots: list[int] | None = None  # default: other slots first, slot 0 last


def fake_announcing_image(label: str, slot: int, chash: str) -> bytes:
    """A fake image whose DATA carries the announcement (hil_mock's ScanRunner prints it)."""
    img = bytearray(P.SLOT_SIZE)
    text = f"{announce.line(_mid(label), chash[:8])}\r".encode() if slot == 0 else b"slot %d" % slot
    img[0 : len(text)] = text
    img[-40:] = bytes(range(1, 41))  # "program" at the top
    return bytes(img)


def _mid(label: str) -> ModuleId:
    from bstool.moduleid import parse_module

    return parse_module(label)


def write_fake_build(
    root: Path,
    modules: Sequence[FakeModule],
    *,
    legs: int = 5,
    modules_per_leg: int = 6,
    chash: str = "0" * 64,
    model: str = "ca1d",
    period: float = 0.5,
    links: Sequence[bf.Wire] = (),
) -> Path:
    """Write ``root`` as a build folder: each module's images and packets, and a manifest
    (the compile-only fields get plausible values)."""
    entries = []
    for fm in modules:
        d = f"modules/{fm.module.label}"
        slots = []
        for n, img in sorted(fm.images.items()):
            (root / d).mkdir(parents=True, exist_ok=True)
            (root / d / f"slot{n}.eeprom").write_bytes(img)
            (root / d / f"slot{n}.packets").write_bytes(b"".join(P.records_for_image(img)))
            slots.append(
                bf.Slot(
                    slot=n,
                    file=f"{d}/main.bsx",
                    source_sha256="0" * 64,
                    program_bytes=0,
                    data_bytes=0,
                    eeprom=f"{d}/slot{n}.eeprom",
                    packets=f"{d}/slot{n}.packets",
                    sha256=hashlib.sha256(img).hexdigest(),
                )
            )
        entries.append(
            bf.Module(
                module=fm.module,
                label=fm.module.label,
                dir=d,
                entry=f"{d}/main.bsx",
                initial_state=fm.initial_state,
                slots=slots,
                ram_bytes=0,
                ram_bytes_available=26,
                pins=list(fm.pins),
                servo=bf.ServoTable([1042 + 111 * s for s in range(16)], []),
                dead_ticks=5,
                timing=bf.Timing(period, period, fm.longest_servo_gap_s),
                ram_map=fm.ram_map,
            )
        )
    order = [
        bf.FlashStep(
            fm.module,
            fm.flash_slots
            if fm.flash_slots is not None
            else [*sorted((n for n in fm.images if n), reverse=True), 0],
        )
        for fm in modules
    ]
    man = bf.Manifest(
        controller=bf.ControllerInfo("fake.json", bf.CONTROLLER_FILE, chash, chash[:8], model),
        robot=bf.RobotSize(legs, modules_per_leg, 16),
        period_s=period,
        tokenized=True,
        link=bf.LinkSettings("protocol/link.md", 4800, 33268, 2, 26, 22, 16, 8, 7, 4, 1500, 5000),
        announcement=announce.DESCRIPTION,
        modules=entries,
        links=list(links),
        flash_order=order,
    )
    root.mkdir(parents=True, exist_ok=True)
    (root / bf.MANIFEST_FILE).write_text(bf.dumps(man), encoding="utf-8")
    return root
