"""``python -m hil_mock serve``: virtual BS2sx modules on ptys, for ``bstool flash --port``."""

from __future__ import annotations

import json
import signal
import sys
import threading
from pathlib import Path

import click

from bstool import fileio
from bstool.errors import InputError
from bstool.moduleid import ModuleId, all_modules, parse_module
from hil_mock.eeprom import Eeprom
from hil_mock.measured import load as load_timing
from hil_mock.perturb import Perturbation, draws_json, perturb_options, perturb_runner, serve_draws
from hil_mock.progdevice import MODEL_IDS, ProgrammingDevice, Runner, default_runner
from hil_mock.ptyendpoint import PtyEndpoint
from hil_mock.realtime import RealtimeRunner
from hil_mock.runners import ScanRunner, preview_runner


@click.group()
def main() -> None:
    """hil_mock: virtual BS2sx modules."""


def _modules(spec: str) -> list[ModuleId]:
    if spec == "all":
        return all_modules(5, 6)
    if spec.isdigit():
        return all_modules(5, 6)[: int(spec)]
    return [parse_module(s) for s in spec.split(",") if s.strip()]


def _runner(kind: str, timing: str = "none") -> Runner | None:
    if kind == "scan":
        return ScanRunner()
    if kind == "none":
        return None
    if timing == "real":  # issue 13 §2: DEBUG bytes leave when the program sends them
        return RealtimeRunner()
    return default_runner() or preview_runner()


@main.command()
@click.option(
    "--modules", default="1", show_default=True, help="all, a count N, or a list like 0.0,2.3."
)
@click.option(
    "--timing",
    type=click.Choice(["real", "none"]),
    default="real",
    show_default=True,
    help="real: answers paced at 9600 baud, slot 0 run in real time; none: at once.",
)
@click.option("--model", type=click.Choice(sorted(MODEL_IDS)), default="BS2sx")
@click.option(
    "--eeprom-dir",
    type=click.Path(path_type=Path),
    help="Keep each module's EEPROM in DIR/L<i>.M<j>.eeprom across runs.",
)
@click.option(
    "--ports-file",
    type=click.Path(path_type=Path),
    help="Also write the module -> pty map as JSON (for bstool flash --all --ports).",
)
@click.option(
    "--runner",
    type=click.Choice(["interpreter", "scan", "none"]),
    default="interpreter",
    show_default=True,
    help="What runs slot 0: the token interpreter, a scan for an ASCII announcement (test "
    "images), or nothing.",
)
@click.option(  # issue 13 §2
    "--timing-model",
    type=click.Path(dir_okay=False),
    help="A bstool.timing/1 file (bstool probe): the stamps' measured timing model.",
)
@perturb_options(add_seed=True, usage_errors=True)  # issue 12 §1
def serve(
    modules: str,
    timing: str,
    model: str,
    eeprom_dir: Path | None,
    ports_file: Path | None,
    runner: str,
    timing_model: str | None,  # issue 13 §2
    perturb: Perturbation,  # issue 12 §1
) -> None:
    """Serve virtual stamps on ptys; prints one "L<i>.M<j> /dev/pts/N" line each. With
    --timing real, slot 0 runs in real time on the interpreter (hil_mock/realtime.py)."""
    try:  # issue 13 §2
        stamp_timing = load_timing(timing_model)
    except InputError as exc:
        raise click.UsageError(f"{exc} ({exc.hint})" if exc.hint else str(exc)) from None
    endpoints: dict[str, PtyEndpoint] = {}
    mids = _modules(modules)
    draws = serve_draws(perturb, mids)  # issue 12 §1
    for mid in mids:
        eeprom = Eeprom(eeprom_dir / f"{mid.label}.eeprom" if eeprom_dir else None)
        module_runner = _runner(runner, timing)
        perturb_runner(module_runner, perturb, draws[mid], stamp_timing)  # issue 12 §1, 13 §2
        device = ProgrammingDevice(eeprom, model=model, runner=module_runner)
        endpoints[mid.label] = PtyEndpoint(device, timing=timing)
    if ports_file:  # before printing, so a reader of stdout finds the file complete
        fileio.write_text(
            ports_file, json.dumps({k: e.path for k, e in endpoints.items()}, indent=1) + "\n"
        )
    for label, ep in endpoints.items():
        click.echo(f"{label} {ep.path}")
    if not perturb.neutral:  # issue 12 §1: what was drawn
        click.echo("perturbations " + json.dumps(draws_json(perturb, draws)), err=True)
    sys.stdout.flush()
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    try:
        done.wait()
    except KeyboardInterrupt:
        pass
    finally:
        for ep in endpoints.values():
            ep.close()


if __name__ == "__main__":
    main()
