"""``bstool twin``: run a compiled robot on 30 virtual BS2sx modules driving the MuJoCo robot."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_failure_time, parse_module
from hil_mock.perturb import Perturbation, perturb_options  # issue 12 §1


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
    metavar="A-B",
    help="Cut the link between modules A and B (e.g. 0.1-0.2); repeatable.",
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
@perturb_options()  # issue 12 §1: --timing-scale --timing-spread --clock-spread ... (one arg)
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
    perturb: Perturbation,  # issue 12 §1
) -> None:
    """Run BUILD (a `bstool compile` output) on the twin: every module's program on its own
    virtual BS2sx, the modules wired as WIRING.md says, each servo driving the simulated robot.
    Prints each module's states against `bstool states`, the disc's distance against `bstool
    simulate`, the measured transition period and servo-pulse gaps against the manifest."""
    if video and no_physics:
        raise click.UsageError("--video needs physics: drop --no-physics")
    if video:
        from bstool.sim.gl import configure_headless_gl

        configure_headless_gl()  # before mujoco is imported
    from hil_mock.robot import RobotTwin, load_build

    b = load_build(build)
    fail_ids = [parse_module(f, b.legs, b.modules) for f in failed]
    die_at = dict(parse_failure_time(d, b.legs, b.modules) for d in die)
    cuts = [_parse_cut(c, b.legs, b.modules) for c in cut]
    ctrl = _controller(b.root, controller)
    eeproms = None
    fleet = None
    if via_flash:
        from hil_mock.fleet import flash_fleet, make_fleet

        fleet = make_fleet(b.legs, b.modules)
        status = flash_fleet(b.root, fleet)
        bad = {k: v for k, v in status.items() if v != "flashed"}
        if bad:
            raise InputError(f"flashing the twins failed: {bad}")
        eeproms = dict(fleet.eeproms)
    try:
        twin = RobotTwin(b, eeproms=eeproms, failed=fail_ids, die=die_at, limp_failed=limp_failed,
                         cut=cuts, noise=link_noise, seed=seed, physics=not no_physics,
                         perturb=perturb)  # fmt: skip
        result = _run(twin, transitions, quiet or as_json, video, timeout_s)
    finally:
        if fleet is not None:
            fleet.close()
    reference = (
        ctrl.states(transitions, failed=fail_ids, failed_at=die_at) if ctrl is not None else None
    )
    sim_distance = None
    if ctrl is not None and not no_physics:
        from hil_mock.check import reference_simulator

        assert reference is not None
        sim_distance = reference_simulator(b).run(reference).distance
    from hil_mock.check import check

    report = check(b, result, reference, transitions, sim_distance)
    if as_json:
        out = report.to_json()
        out["states"] = result.state_array(b.legs, b.modules, transitions).tolist()
        out["path"] = result.path.tolist()
        out["virtual_seconds"] = result.virtual_seconds
        out["instructions"] = result.instructions
        out["perturbations"] = twin.perturb.report()  # issue 12 §1
        click.echo(json.dumps(out))
    else:
        _print(report, result)
    if reference is not None and not report.states_equal:
        sys.exit(1)


def _run(twin, transitions: int, quiet: bool, video: str | None, timeout_s: float | None):
    from tqdm import tqdm

    with tqdm(total=transitions + 1, unit="transition", disable=quiet or None,
              desc="twin", file=sys.stderr) as bar:  # fmt: skip
        if not video:
            return twin.run(transitions, progress=bar.update, timeout_s=timeout_s)
        from bstool.sim.video import VideoRecorder
        from hil_mock.robot import CHUNK_STEPS, RobotTwin

        model = twin.sim.model
        with VideoRecorder(model, video) as rec:
            every = max(1, round(rec.steps_per_frame(model) / CHUNK_STEPS))
            chunks = [0]

            def on_chunk(t: RobotTwin) -> None:
                chunks[0] += 1
                if chunks[0] % every == 0 and t.sim is not None:
                    rec.frame(t.sim.data)

            return twin.run(
                transitions, progress=bar.update, on_chunk=on_chunk, timeout_s=timeout_s
            )


def _controller(root: Path, given: str | None):
    from bstool.controllers import load_controller

    if given:
        return load_controller(given)
    default = root / "controller.json"
    return load_controller(default) if default.is_file() else None


def _parse_cut(text: str, legs: int, modules: int) -> tuple[ModuleId, ModuleId]:
    parts = text.split("-")
    if len(parts) != 2:
        raise InputError(f"bad --cut {text!r}: expected A-B, e.g. 0.1-0.2")
    return parse_module(parts[0], legs, modules), parse_module(parts[1], legs, modules)


def _print(report, result) -> None:
    T = report.transitions
    if report.sim_distance is not None or report.mismatched or report.states_equal:
        verdict = "EQUAL to" if report.states_equal else "DIFFERENT from"
        click.echo(f"states:     every module's {T + 1} states are {verdict} `bstool states`")
    if report.first_mismatch:
        fm = report.first_mismatch
        click.echo(
            f"            first difference: module {fm['module']} at transition "
            f"{fm['transition']}: twin {fm['twin']} vs reference {fm['reference']}"
        )
        click.echo(f"            modules that differ: {', '.join(map(str, report.mismatched))}")
    if len(result.path) > 1:
        line = f"distance:   twin {report.twin_distance * 100:.2f} cm"
        if report.sim_distance is not None:
            line += f", simulator {report.sim_distance * 100:.2f} cm"
        click.echo(line)
    click.echo(f"period:     {report.period_mean:.3f} s ± {report.period_std:.3f} "
               f"(nominal {report.period_nominal:.3f} s)")  # fmt: skip
    click.echo(f"servo gaps: longest {report.servo_gap_max * 1000:.1f} ms "
               f"(manifest estimate {report.servo_gap_estimate * 1000:.1f} ms)")  # fmt: skip
    click.echo(f"stalled:    {', '.join(map(str, report.stalled)) or 'none'}")
    click.echo(
        f"announced:  {'all modules as expected' if report.announcements_ok else 'MISMATCH'}"
    )
    click.echo(f"virtual:    {result.virtual_seconds:.2f} s, {result.instructions} instructions")
