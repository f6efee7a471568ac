"""``bstool model``: the generated MJCF robot model, or a summary of it."""

from __future__ import annotations

import click

from bstool import fileio, outputs
from bstool.commands.robot_option import robot_option
from bstool.errors import InputError
from bstool.robot import RobotSpec, robotfile, to_mjcf


@click.command("model")
@click.option(
    "--xml",
    "xml_out",
    is_flag=False,
    flag_value="-",
    default=None,
    metavar="[FILE|-]",
    help="Write the MJCF to FILE, or to standard output with '-' or no value.",
)
@click.option("--legs", type=click.IntRange(min=1), default=5, show_default=True)
@click.option("--modules", type=click.IntRange(min=1), default=6, show_default=True)
@click.option(
    "--lead-axis",
    type=click.Choice(["vertical", "horizontal"]),
    default="vertical",
    show_default=True,
    help="Hinge axis of the lead module; the others alternate.",
)
@robot_option
@click.pass_context
def command(
    ctx: click.Context,
    xml_out: str | None,
    legs: int,
    modules: int,
    lead_axis: str,
    robot: str | None,
) -> None:
    """Generate the robot's MuJoCo model (MJCF) from the robot description (--robot FILE, or
    the default robot). Without --xml, print a summary of the model."""
    if xml_out and xml_out != "-":
        outputs.check_file(xml_out, "model file")
    if robot is not None:
        from click.core import ParameterSource

        typed = [name for name in ("legs", "modules", "lead_axis")
                 if ctx.get_parameter_source(name) is not ParameterSource.DEFAULT]  # fmt: skip
        if typed:
            raise InputError(
                f"--{typed[0].replace('_', '-')} does not combine with --robot",
                hint="set it in the robot file",
            )
        spec = robotfile.load(robot).spec
    else:
        spec = RobotSpec(legs=legs, modules=modules, lead_axis=lead_axis)  # type: ignore[arg-type]
    xml = to_mjcf(spec)
    if xml_out == "-":
        click.echo(xml, nl=False)
        return
    if xml_out:
        fileio.write_text(xml_out, xml)
        click.echo(f"wrote {xml_out} ({legs} legs × {modules} modules)", err=True)
        return
    from bstool.robot import build_model

    model = build_model(spec)
    click.echo(f"brittle star robot: {legs} legs × {modules} modules, lead axis {lead_axis}")
    click.echo(
        f"bodies {model.nbody - 1}, hinges {model.njnt - 1}, actuators {model.nu},"
        f" mass {model.body_subtreemass[1]:.3f} kg, timestep {model.opt.timestep * 1000:g} ms"
    )
    click.echo(
        f"servo: stall {spec.servo_torque} N·m, {spec.servo_speed} s/60°, kp {spec.servo_kp:g}"
        f" N·m/rad, damping {spec.servo_damping:.4f} N·m·s/rad;"
        f" transition {spec.transition_time:g} s"
    )
    click.echo("write the MJCF with: bstool model --xml robot.xml")
