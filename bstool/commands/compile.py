"""``bstool compile``: a controller file → PBASIC per module, EEPROM images, manifest, wiring."""

from __future__ import annotations

import click

from bstool.commands.robot_option import resolve_robot, robot_option


@click.command("compile")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default="build",
    show_default=True,
    help="Output folder (replaced as a whole; never left half-written).",
)
@click.option(
    "--calibration",
    type=click.Path(dir_okay=False),
    default=None,
    help="Servo calibration JSON (bstool.servos/1) overriding the defaults per module.",
)
@click.option(
    "--period",
    type=float,
    default=None,
    metavar="S",
    help="Seconds per transition: sets the programs' HoldFrames and the reference simulation"
    " (default: the simulator's transition time).",
)
@click.option(
    "--module",
    "modules",
    multiple=True,
    metavar="L.M",
    help="Compile only this module (leg.module, 0 = lead); repeatable.",
)
@click.option(
    "--force", is_flag=True, help="Replace a non-empty output folder that is not a bstool build."
)
@click.option(  # issue 13 §2
    "--timing",
    "timing_file",
    type=click.Path(dir_okay=False),
    help="A bstool.timing/1 file (bstool probe): estimate with the stamps' measured timing.",
)
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
@robot_option
def command(
    controller: str,
    out_dir: str,
    calibration: str | None,
    period: float | None,
    modules: tuple[str, ...],
    force: bool,
    timing_file: str | None,  # issue 13 §2
    quiet: bool,
    robot: str | None,
) -> None:
    """Compile CONTROLLER (best.json) into one PBASIC program per module (docs/compile.md):
    sources, tokenized slot images, manifest.json and WIRING.md in the output folder."""
    import sys

    from bstool.compile import compile_controller
    from bstool.controllers import load_controller

    if robot is not None:
        resolve_robot(robot, load_controller(controller).robot, controller, quiet=quiet)
    result = compile_controller(
        controller,
        out_dir,
        calibration=calibration,
        period=period,
        modules=modules,
        progress=not quiet and sys.stderr.isatty(),
        force=force,
        timing=timing_file,  # issue 13 §2
        robot=robot,
    )
    if quiet:
        return
    slots = sum(len(m.slots) for m in result.modules)
    click.echo(
        f"compiled {len(result.modules)} modules ({slots} slots, tokenized) for controller "
        f"{result.controller_hash[:8]} into {result.out_dir}"
    )
    gap = max(m.timing["longest_servo_gap_s"] for m in result.modules)
    period = max(m.timing["nominal_transition_s"] for m in result.modules)
    hold = result.manifest.link.hold_frames
    click.echo(
        f"estimated period {period:.3f} s (asked {result.manifest.period_s:g} s: HoldFrames "
        f"{hold}); longest servo gap {gap * 1000:.1f} ms (timing model)"
    )
