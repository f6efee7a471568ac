"""``bstool demo``: the whole chain on a built-in controller, side by side with the simulator.

compile → tokenize → flash 30 virtual BS2sx modules through the programming protocol → run
them on the twin driving the MuJoCo robot → compare with ``bstool states`` and ``simulate``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import click

import hil_mock  # noqa: F401  (registers the twin's bstwin:// serial URL handler)
from bstool.builtin import DEFAULT_MODEL, MODELS, builtin_controller
from bstool.commands.robot_option import resolve_robot, robot_option


@click.command("demo")
@click.option(
    "--model",
    type=click.Choice(MODELS),
    default=DEFAULT_MODEL,
    show_default=True,
    help="Which built-in evolved controller to run.",
)
@click.option(
    "--controller",
    type=click.Path(dir_okay=False),
    help="Run this controller file instead of a built-in one.",
)
@click.option("-T", "--transitions", type=click.IntRange(min=1), default=30, show_default=True)
@click.option(
    "--fail",
    "failed",
    multiple=True,
    metavar="L.M",
    help="A dead module on the twin (and the same failure in the reference).",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(file_okay=False),
    help="Keep the build here (default: a temporary directory).",
)
@click.option(
    "--force", is_flag=True, help="With --out: replace a non-empty folder that is not a build."
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bars.")
@robot_option
def command(
    model: str,
    controller: str | None,
    transitions: int,
    failed: tuple[str, ...],
    out: str | None,
    force: bool,
    quiet: bool,
    robot: str | None,
) -> None:
    """Show that what runs on the stamps is what evolved: compile a controller, flash it into
    30 virtual BS2sx modules over the serial programming protocol, run them on the simulated
    robot, and print what the simulator predicted next to what the twin did."""
    source = Path(controller) if controller else builtin_controller(model)
    if out:  # before any work or output: a folder it may not replace, or cannot write
        from bstool.compile.build import check_output

        check_output(Path(out), force=force, protect=(source,))
    with tempfile.TemporaryDirectory(prefix="bstool-demo-") as tmp:
        build_dir = Path(out) if out else Path(tmp) / "build"
        ok = _demo(source, build_dir, transitions, failed, quiet, force=force, robot=robot)
    if not ok:
        click.get_current_context().exit(1)


def _demo(
    source: Path,
    build_dir: Path,
    transitions: int,
    failed: tuple[str, ...],
    quiet: bool,
    *,
    force: bool = False,
    robot: str | None = None,
) -> bool:
    from tqdm import tqdm

    from bstool import buildfile
    from bstool.compile import compile_controller
    from bstool.controllers import load_controller
    from bstool.moduleid import parse_module
    from hil_mock.check import verdict_line
    from hil_mock.session import TwinOptions, run_twin

    say = click.echo
    ctrl = load_controller(source)
    fail_ids = [parse_module(f, ctrl.legs, ctrl.modules) for f in failed]
    say(f"controller   {source.name}: {ctrl.model}, {ctrl.legs}×{ctrl.modules} modules, "
        f"hash {ctrl.hash()[:8]}")  # fmt: skip

    t0 = time.perf_counter()
    if robot is not None:
        resolve_robot(robot, ctrl.robot, str(source))  # says so when it differs
    result = compile_controller(source, build_dir, force=force, robot=robot)
    slots = sum(len(m.slots) for m in result.manifest.modules)
    say(f"compile      {len(result.manifest.modules)} PBASIC programs, {slots} slots "
        f"tokenized ({time.perf_counter() - t0:.1f} s) -> {build_dir}")  # fmt: skip

    build = buildfile.load(build_dir)
    with tqdm(total=transitions + 1, unit="transition", desc="twin", disable=quiet or None,
              file=sys.stderr) as bar:  # fmt: skip
        options = TwinOptions(transitions=transitions, failed=fail_ids, via_flash=True,
                              fleet_name="demo", controller=ctrl, progress=bar.update)  # fmt: skip
        report = run_twin(build, options)
    status = report.flash_status or {}
    flashed = sum(1 for s in status.values() if s == "flashed")
    say(f"flash        {flashed}/{len(status)} twins programmed over the serial protocol "
        f"({report.flash_seconds:.1f} s)")  # fmt: skip
    run, rep = report.result, report.check
    sim_distance = report.sim_distance if report.sim_distance is not None else float("nan")
    say("")
    say(f"{'':26}{'simulator':>14}{'twin (stamps)':>18}")
    say(f"{'distance (cm)':26}{sim_distance * 100:14.2f}{run.distance * 100:18.2f}")
    states_text = {"equal": "equal", "stalled": f"{len(rep.stalled)} modules stalled"}.get(
        rep.verdict, f"{len(rep.mismatched)} modules differ"
    )
    say(f"{'states, ' + str(transitions) + ' transitions':26}{'reference':>14}{states_text:>18}")
    period = ("not measured" if rep.period_mean is None or rep.period_std is None
              else f"{rep.period_mean:.3f} ±{rep.period_std:.3f}")  # fmt: skip
    say(f"{'transition period (s)':26}{build.period:14.3f}{period:>18}")
    say(f"{'longest servo gap (ms)':26}{rep.servo_gap_estimate * 1000:14.1f}"
        f"{rep.servo_gap_max * 1000:18.1f}")  # fmt: skip
    announced = "all correct" if rep.announcements_ok else "WRONG"
    say(f"{'start-up announcements':26}{'':14}{announced:>18}")
    say(f"{'twin speed':26}{'':14}{run.virtual_seconds / report.twin_seconds:15.1f}× real time")
    if not rep.states_equal:
        say(f"states: {verdict_line(rep, run)}")
    say("")
    say("The states are the exact check. Distances agree only roughly: the stamps keep their own")
    say("clocks (the period above), and contact-rich walking amplifies a few ms of timing after")
    say("about 10 transitions (docs/twin.md, path tolerance).")
    return rep.states_equal and rep.announcements_ok
