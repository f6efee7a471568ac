"""``bstool flash``: upload images to BS2sx modules over a serial port (docs/flash.md)."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
from tqdm import tqdm

import hil_mock  # noqa: F401  (registers bstwin://, the twin's serial URLs)
from bstool import outputs
from bstool.errors import DeviceError, InputError
from bstool.flash import protocol as P
from bstool.flash.flasher import (
    PROGRESS_FILE,
    ModuleReport,
    check_module,
    flash_all,
    flash_module,
    read_ports_file,
)
from bstool.flash.port import resolve_auto
from bstool.flash.session import FAST, Progress, Timing
from bstool.flash.target import ModulePlan, load_target


def _timing(attempts: int) -> Timing:
    # BSTOOL_FLASH_FAST=1 shortens every wait (tests against an instant twin).
    base = FAST if os.environ.get("BSTOOL_FLASH_FAST") == "1" else Timing()
    return Timing(**{**base.__dict__, "attempts": attempts})


@click.command("flash")
@click.argument("target", type=click.Path(path_type=Path))
@click.option("--port", "-p", help="Device path, pyserial URL (socket://, bstwin://) or auto.")
@click.option("--module", "-m", "module", help="Module L.M to flash from a build directory.")
@click.option("--slot", type=click.IntRange(0, 7), help="Flash only this slot.")
@click.option("--all", "every", is_flag=True, help="Walk every module of the build in order.")
@click.option(
    "--ports",
    "ports_file",
    type=click.Path(path_type=Path),
    help="JSON module -> port; with --all runs without prompts.",
)
@click.option("--trace", is_flag=True, help="Hex-dump every byte each way (stderr).")
@click.option("--baud", default=P.BAUD, show_default=True, help="Line speed.")
@click.option("--attempts", default=3, show_default=True, help="Connect attempts (each resets).")
@click.option("--no-listen", is_flag=True, help="Do not wait for the start-up announcement.")
@click.option(
    "--force",
    is_flag=True,
    help="With --all: flash every module, even those the progress file and the stamp's "
    "announcement say run this build already.",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bars or chatter.")
def command(
    target: Path,
    port: str | None,
    module: str | None,
    slot: int | None,
    every: bool,
    ports_file: Path | None,
    trace: bool,
    baud: int,
    attempts: int,
    no_listen: bool,
    force: bool,
    quiet: bool,
) -> None:
    """Upload TARGET (a compile output dir, a .bsx file or a controller file) into BS2sx
    modules over the programming protocol, verifying every byte's echo and every record's
    acknowledgement, then check the start-up announcement names the right module/controller.

    --all resumes: a module flash-progress.json calls flashed is skipped only when its stamp,
    restarted, announces this build's module and controller; --force flashes them all.
    """
    if port is None and ports_file is None:
        raise InputError("give the port: --port /dev/ttyUSB0 (or auto, or a URL)")
    if ports_file is not None and not every and module is None:
        every = True
    from bstool.compile import compile_controller  # jinja and the templates: only when needed

    plan_target = load_target(
        target, module=module, slot=slot, every_module=every, compiler=compile_controller
    )
    timing = _timing(attempts)

    def say(msg: str) -> None:
        if not quiet or msg.startswith("warning"):
            click.echo(msg, err=True)

    tracer: Callable[[str], None] | None = (lambda m: click.echo(m, err=True)) if trace else None
    bars = not quiet and sys.stderr.isatty()

    def resolved(port_name: str) -> str:
        """``auto``: the adapter plugged in (asked once per module when several are)."""
        if port_name == "auto":
            return resolve_auto(_choose if sys.stdin.isatty() else None)
        return port_name

    def one(port_name: str, plan: ModulePlan) -> ModuleReport:
        port_name = resolved(port_name)
        bar: list[Any] = []

        def start(slot_no: int, total: int) -> None:
            for b in bar:
                b.close()
            bar[:] = [
                tqdm(
                    total=total,
                    desc=f"{plan.label} slot {slot_no}",
                    unit="rec",
                    disable=not bars,
                    file=sys.stderr,
                    leave=True,
                )
            ]

        def step(p: Progress) -> None:
            if bar:
                bar[0].update(p.done - bar[0].n)

        try:
            report = flash_module(
                port_name,
                plan,
                baud=baud,
                timing=timing,
                log=say,
                trace=tracer,
                progress=step,
                on_slot_start=start,
                listen=not no_listen,
            )
        finally:
            for b in bar:
                b.close()
        _print_report(report, plan, baud, listened=not no_listen)
        return report

    ports = read_ports_file(ports_file) if ports_file else None
    if not every:
        plan = plan_target.modules[0]
        if port is None and ports is not None:
            if plan.module not in ports:
                raise InputError(f"{ports_file} names no port for {plan.label}")
            port = ports[plan.module]
        assert port is not None
        one(port, plan)
        return

    if plan_target.build_dir is not None:  # the resume file is written before each module
        outputs.check_file(plan_target.build_dir / PROGRESS_FILE, "flash progress file")

    def port_for(plan: ModulePlan) -> str | None:
        if ports is not None:
            if plan.module not in ports:
                say(f"{plan.label}: no port in {ports_file}; skipped")
                return None
            return ports[plan.module]
        try:
            answer = click.prompt(
                f"connect {plan.label}, Enter to flash, s to skip, q to quit",
                default="",
                show_default=False,
                err=True,
            )
        except click.exceptions.Abort as exc:
            if not isinstance(exc.__context__, EOFError):
                raise  # Ctrl-C at the prompt
            raise InputError(
                f"flash --all asks which module is connected, but standard input ended "
                f"(no terminal?) before {plan.label}",
                hint="run it in a terminal, or give --ports FILE mapping each module to its "
                'port, e.g. {"L0.M0": "/dev/ttyUSB0", ...}',
            ) from None
        answer = answer.strip().lower()
        if answer in ("q", "s"):
            return "quit" if answer == "q" else None
        return None if port is None else resolved(port)  # once: check and flash share it

    def check(port_name: str, plan: ModulePlan) -> str | None:
        return check_module(port_name, plan, baud=baud, timing=timing)

    result = flash_all(
        plan_target,
        port_for=port_for,
        flash=one,
        log=say,
        check=None if no_listen else check,
        force=force,
    )
    click.echo("\nmodule   result")
    for label, status in result.status.items():
        extra = f"  {result.messages[label]}" if label in result.messages else ""
        click.echo(f"{label:<8} {status}{extra}")
    counts = {s: list(result.status.values()).count(s) for s in ("flashed", "failed", "skipped")}
    click.echo(", ".join(f"{n} {s}" for s, n in counts.items()))
    if result.failed:
        raise DeviceError(
            f"{len(result.failed)} module(s) failed: {', '.join(result.failed)}",
            hint="fix them and run the same command again: modules whose stamps announce this "
            "build are skipped (--force flashes them all)",
        )


def _choose(ports: list[str]) -> str:
    for i, p in enumerate(ports, 1):
        click.echo(f"  {i}: {p}", err=True)
    n = click.prompt("which port", type=click.IntRange(1, len(ports)), err=True)
    return ports[n - 1]


def _print_report(report: ModuleReport, plan: ModulePlan, baud: int, *, listened: bool) -> None:
    version = f" (BS2sx v{report.version})" if report.version else ""
    click.echo(f"{report.label}: flashed on {report.port}{version}: {report.summary(baud)}")
    heard = report.announcement
    if heard is not None:
        click.echo(f"module L{heard[0]}.M{heard[1]} runs controller {heard[2]}")
    elif listened and (plan.module is not None or plan.controller_hash is not None):
        click.echo(
            f"warning: no start-up announcement from {report.label}: cannot confirm what runs",
            err=True,
        )
