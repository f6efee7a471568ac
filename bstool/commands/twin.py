"""``bstool twin``: run a compiled robot on 30 virtual BS2sx modules driving the MuJoCo robot."""

from __future__ import annotations

import json
import math
import sys
from typing import TYPE_CHECKING

import click

import hil_mock  # noqa: F401  (registers the twin's bstwin:// serial URL handler)
from bstool.commands.robot_option import resolve_robot, robot_option
from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_failure_time, parse_module
from hil_mock.perturb import Perturbation, perturb_options

if TYPE_CHECKING:
    from bstool.controllers import Controller
    from hil_mock.check import TwinCheck
    from hil_mock.twin_result import TwinResult


@click.command("twin")
@click.argument("build", type=click.Path(file_okay=False))
@click.option("-T", "--transitions", type=click.IntRange(min=1), default=30, show_default=True)
@click.option(
    "--fail",
    "failed",
    multiple=True,
    metavar="L.M",
    help="A dead module: its program never runs (silent links); its servo holds R^0.",
)
@click.option(
    "--die",
    "die",
    multiple=True,
    metavar="L.M@T",
    help="A module that dies during the run, once it has shown and sent S^T; its servo then "
    "holds S^T. Compared with `bstool states --fail-at L.M@T`; repeatable.",
)
@click.option(
    "--limp-failed", is_flag=True, help="Failed and dying modules' servos go limp instead."
)
@click.option(
    "--cut",
    multiple=True,
    metavar="A-B[@S] | A>B[@S]",
    help="Cut the link between modules A and B (e.g. 0.1-0.2) from power-up, or from S "
    "seconds of virtual time (0.1-0.2@3.5: a wire coming loose in a running robot); A>B: a "
    "one-way wire, A's bytes to B are lost and B's reach A (a broken receive line at B); "
    "repeatable.",
)
@click.option(
    "--link-noise",
    type=click.FloatRange(0, 1),
    default=0.0,
    show_default=True,
    help="Chance that a byte on a link is dropped or has a bit flipped.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of every random draw.")
@click.option(
    "--controller",
    type=click.Path(dir_okay=False),
    help="Controller to compare with (default: the build's controller.json).",
)
@click.option(
    "--flash",
    "via_flash",
    is_flag=True,
    help="Flash 30 fresh twins through the programming protocol first (instead of "
    "loading the images directly).",
)
@click.option("--no-physics", is_flag=True, help="Only the stamps (faster; no path).")
@click.option(
    "--video",
    type=click.Path(dir_okay=False),
    help="Render the twin's robot offscreen to an MP4 file.",
)
@click.option(
    "--timeout",
    "timeout_s",
    type=float,
    default=None,
    help="Stop after this many seconds of virtual time (default: generous).",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@click.option(  # issue 13 §2
    "--timing",
    "timing_file",
    type=click.Path(dir_okay=False),
    help="A bstool.timing/1 file (bstool probe): the stamps' measured timing model.",
)
@perturb_options()  # --timing-scale --timing-spread --clock-spread --start-spread --reset ...
@robot_option
def command(
    build: str,
    transitions: int,
    failed: tuple[str, ...],
    die: tuple[str, ...],
    limp_failed: bool,
    cut: tuple[str, ...],
    link_noise: float,
    seed: int,
    controller: str | None,
    via_flash: bool,
    no_physics: bool,
    video: str | None,
    timeout_s: float | None,
    as_json: bool,
    quiet: bool,
    timing_file: str | None,  # issue 13 §2
    perturb: Perturbation,
    robot: str | None,
) -> None:
    """Run BUILD (a `bstool compile` output) on the twin: every module's program on its own
    virtual BS2sx, the modules wired as WIRING.md says, each servo driving the simulated robot.
    Prints each module's states against `bstool states`, the disc's distance against `bstool
    simulate`, the measured transition period and servo-pulse gaps against the manifest."""
    if video and no_physics:
        raise click.UsageError("--video needs physics: drop --no-physics")
    if video:
        from bstool import outputs
        from bstool.sim.gl import configure_headless_gl

        outputs.check_file(video, "video")  # before the run, not after it

        configure_headless_gl()  # before mujoco is imported
    from tqdm import tqdm

    from bstool import buildfile
    from hil_mock import measured
    from hil_mock.session import TwinOptions, run_twin

    timing = measured.load(timing_file)  # issue 13 §2: the measured timing model
    b = buildfile.load(build)  # refuses a build whose images differ from the manifest
    if robot is not None:  # the build's programs on another robot's physics
        from hil_mock.body import with_robot

        b = with_robot(b, resolve_robot(robot, b.manifest.robot_values, build, quiet=as_json))
    fail_ids = [parse_module(f, b.legs, b.modules) for f in failed]
    die_at = dict(parse_failure_time(d, b.legs, b.modules) for d in die)
    parsed = [_parse_cut(c, b.legs, b.modules) for c in cut]
    cuts = [(x, y) for x, y, at, one in parsed if at is None and not one]
    cut_at = {(x, y): at for x, y, at, one in parsed if at is not None and not one}
    one_way = {(x, y): at or 0.0 for x, y, at, one in parsed if one}
    with tqdm(total=transitions + 1, unit="transition", disable=quiet or as_json or None,
              desc="twin", file=sys.stderr) as bar:  # fmt: skip
        options = TwinOptions(
            transitions=transitions,
            failed=fail_ids,
            die=die_at,
            limp_failed=limp_failed,
            cut=cuts,
            cut_at=cut_at,
            one_way=one_way,
            noise=link_noise,
            seed=seed,
            physics=not no_physics,
            via_flash=via_flash,
            controller=_controller(controller),
            timeout_s=timeout_s,
            video=video,
            progress=bar.update,
            perturb=perturb,
            timing=timing,
        )
        run = run_twin(b, options)
    report, result = run.check, run.result
    if as_json:
        out = report.to_json()
        out["states"] = result.state_array(b.legs, b.modules, transitions).tolist()
        out["path"] = result.path.tolist()
        out["virtual_seconds"] = result.virtual_seconds
        out["instructions"] = result.instructions
        out["perturbations"] = run.perturbations
        click.echo(json.dumps(out))
    else:
        _print(report, result)
    if not run.ok:
        click.get_current_context().exit(1)


def _controller(given: str | None) -> Controller | None:
    """``--controller``; without it the twin compares with the build's controller.json."""
    from bstool.controllers import load_controller

    return load_controller(given) if given else None


def _parse_cut(text: str, legs: int, modules: int) -> tuple[ModuleId, ModuleId, float | None, bool]:
    """``A-B`` (from power-up), ``A-B@S`` (from S seconds of virtual time), ``A>B`` or
    ``A>B@S`` (one-way: A's bytes to B lost): (A, B, S or None, one-way)."""
    pair, sep, when = text.partition("@")
    one_way = ">" in pair
    parts = pair.split(">" if one_way else "-")
    at: float | None = None
    if sep:
        try:
            at = float(when)
        except ValueError:
            at = -1.0
    if len(parts) != 2 or (at is not None and not 0.0 <= at < 1e6):
        raise InputError(
            f"bad --cut {text!r}: expected A-B, A-B@S, A>B or A>B@S",
            hint="e.g. 0.1-0.2 (cut from power-up), 0.1-0.2@3.5 (from 3.5 s of virtual time), "
            "0.1>0.2 (one-way: 0.1's bytes to 0.2 are lost); S: seconds, >= 0",
        )
    a, b = (parse_module(x.strip(), legs, modules) for x in parts)
    return a, b, at, one_way


def _print(report: TwinCheck, result: TwinResult) -> None:
    from hil_mock.check import verdict_line  # imports mujoco: after the GL backend is chosen

    click.echo(f"states:     {verdict_line(report, result)}")
    for note in report.notes:
        click.echo(f"            note: {note}")
    if report.first_mismatch:
        fm = report.first_mismatch
        click.echo(
            f"            first difference: module {fm['module']} at transition "
            f"{fm['transition']}: twin {fm['twin']} vs reference {fm['reference']}"
        )
        click.echo(f"            modules that differ: {', '.join(map(str, report.mismatched))}")
    if len(result.path) > 1:
        line = f"distance:   twin {report.twin_distance * 100:.2f} cm"
        if report.stamp_distance is not None:
            line += f", stamp-timed simulator {report.stamp_distance * 100:.2f} cm"
        if report.sim_distance is not None:
            line += f", simulator {report.sim_distance * 100:.2f} cm"
        click.echo(line)
    estimates = (f"(manifest estimate {report.period_estimate:.3f} s, "
                 f"reference {report.period_nominal:.3f} s)")  # fmt: skip
    if report.period_mean is None or report.period_std is None:
        click.echo(f"period:     not measured: no module made two transitions {estimates}")
    else:
        click.echo(f"period:     {report.period_mean:.3f} s ± {report.period_std:.3f} {estimates}")
    if math.isfinite(report.moving_s):
        click.echo(f"start-up:   every module moving at {report.moving_s:.2f} s (the period "
                   "counts the transitions from there)")  # fmt: skip
    click.echo(f"servo gaps: longest {report.servo_gap_max * 1000:.1f} ms "
               f"(manifest estimate {report.servo_gap_estimate * 1000:.1f} ms)")  # fmt: skip
    for mid, off in report.servo_outages.items():
        click.echo(f"            {mid} without pulses for {off:.2f} s across its own power-off")
    click.echo(f"stalled:    {', '.join(map(str, report.stalled)) or 'none'}")
    click.echo(
        f"announced:  {'all modules as expected' if report.announcements_ok else 'MISMATCH'}"
    )
    click.echo(f"virtual:    {result.virtual_seconds:.2f} s, {result.instructions} instructions")
