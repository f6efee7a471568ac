"""``bstool probe``: measure a stamp's timing, write a ``bstool.timing/1`` file (docs/probe.md)."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import click
from tqdm import tqdm

import hil_mock  # noqa: F401  (registers bstwin://, the twin's serial URLs)
from bstool import timingfile
from bstool.flash.port import resolve_auto
from bstool.flash.session import FAST, Timing
from bstool.probe import probe
from bstool.probe.measure import ProbeResult


def _line(name: str, c: timingfile.Coefficient, default: timingfile.Coefficient) -> str:
    sd = "not measured" if c.sd is None else f"± {c.sd:.3g}"
    return f"  {name:<24} {c.value:10.4g} {sd:<14} (model {default.value:g})"


@click.command("probe")
@click.option("--port", "-p", required=True, help="Device path, pyserial URL or auto.")
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, dir_okay=False),
    default=Path("stamp-timing.json"),
    show_default=True,
    help="The timing file to write.",
)
@click.option("--quick", is_flag=True, help="Shorter loops and 3 repeats (~8 s; less precise).")
@click.option(
    "--repeats", type=click.IntRange(1, 20), help="Repeats of every loop (default 5, quick 3)."
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or chatter.")
def command(
    port: str, output: Path, quick: bool, repeats: int | None, as_json: bool, quiet: bool
) -> None:
    """Flash a measurement program to the stamp on PORT (it replaces the module's program:
    flash that again afterwards), time the marker bytes it sends between loops of each
    instruction kind, PAUSE, PULSOUT, SERIN timeouts and SEROUT bytes, fit the timing model's
    coefficients with their uncertainty and write them to OUTPUT, for compile/twin --timing."""
    from bstool import outputs

    outputs.check_file(output, "timing file")  # before flashing and measuring, not after
    if port == "auto":
        port = resolve_auto()
    base = FAST if os.environ.get("BSTOOL_FLASH_FAST") == "1" else Timing()

    def say(msg: str) -> None:
        if not quiet or msg.startswith("warning"):
            click.echo(msg, err=True)

    bar: list[Any] = []

    def tick(total: int) -> None:
        if not bar:
            bar.append(
                tqdm(
                    total=total,
                    desc="probe",
                    unit="marker",
                    disable=quiet or not sys.stderr.isatty(),
                    file=sys.stderr,
                )
            )
        bar[0].update(1)

    try:
        result = probe(port, quick=quick, repeats=repeats, timing=base, log=say, on_marker=tick)
    finally:
        for b in bar:
            b.close()
    timingfile.dump(result.model, output)
    if as_json:
        click.echo(json.dumps(_json(result, output)))
        return
    _print(result, output)


def _json(result: ProbeResult, output: Path) -> dict[str, Any]:
    m = result.model
    return {
        "port": result.port,
        "output": str(output),
        "instruction_time_ratio": m.instruction_time_ratio.value,
        "instruction_time_ratio_sd": m.instruction_time_ratio.sd,
        "coefficients": {n: c.to_json() for n, c in m.coefficients().items()},
        "markers": result.markers,
        "lost": result.lost,
        "seconds": result.seconds,
    }


def _print(result: ProbeResult, output: Path) -> None:
    m = result.model
    r = m.instruction_time_ratio
    click.echo(
        f"{result.port}: statements take {r.value:.4f} ± {r.sd or 0:.4f} × the timing model "
        f"({result.markers} markers, {result.lost} lost, {result.seconds:.1f} s)"
    )
    d = timingfile.DEFAULT.coefficients()
    for name, c in m.coefficients().items():
        click.echo(_line(name, c, d[name]))
    click.echo(f"wrote {output}: use it with bstool compile --timing / bstool twin --timing")
