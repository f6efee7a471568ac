"""``bstool rotate``: steer by shifting the legs' parameters (paper §5.2)."""

from __future__ import annotations

import json

import click

from bstool import outputs
from bstool.commands.robot_option import robot_option
from bstool.commands.robot_option import say_note as _say_note
from bstool.controllers import save_controller
from bstool.experiments import common
from bstool.experiments.paths import heading_deg, wrap_deg
from bstool.experiments.rotation import choose_rotation, rotate_controller


@click.command("rotate")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option(
    "--legs",
    "legs",
    type=int,
    default=None,
    help="Shift by R legs: leg i gets leg i-R's parameters; turns by R·360°/n.",
)
@click.option(
    "--heading",
    type=float,
    default=None,
    help="Pick the shift that heads closest to this direction (degrees anticlockwise "
    "from +x) and report the residual error.",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False),
    required=True,
    help="Where to write the rotated controller.",
)
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=1),
    default=None,
    help="Transitions for measuring headings (default: max_trans, else 30).",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@robot_option
def command(
    controller: str,
    legs: int | None,
    heading: float | None,
    out: str,
    transitions: int | None,
    as_json: bool,
    robot: str | None,
) -> None:
    """Write a copy of CONTROLLER whose legs' parameters are shifted, so the robot walks the
    same gait in another direction. Both headings are measured in simulation."""
    if (legs is None) == (heading is None):
        raise click.UsageError("give exactly one of --legs R or --heading DEG")
    outputs.check_file(out, "rotated controller")
    from bstool.sim.simulator import Simulator

    loaded = common.load(controller, robot)
    _say_note(loaded.note, as_json)
    n = loaded.controller.legs
    T = common.default_transitions(loaded.controller, transitions)
    sim = Simulator(loaded.spec)
    base = heading_deg(sim.run(loaded.controller.states(T)).path)
    choice = None
    if heading is not None:
        choice = choose_rotation(base, heading, n)
        legs = choice.legs
    assert legs is not None
    rotated = rotate_controller(loaded.controller, legs)
    save_controller(rotated, out)
    measured = heading_deg(sim.run(rotated.states(T)).path)
    predicted = wrap_deg(base + (legs % n) * 360.0 / n)
    report = {
        "controller": loaded.name, "out": out, "legs": legs % n,
        "heading_before": base, "heading_predicted": predicted, "heading_measured": measured,
        "measured_minus_predicted": wrap_deg(measured - predicted),
    }  # fmt: skip
    if choice is not None:
        report |= {"wanted": heading, "residual": choice.residual}
    if as_json:
        click.echo(json.dumps(report))
        return
    click.echo(f"wrote {out}: legs shifted by {legs % n} (turn of {(legs % n) * 360 / n:g}°)")
    click.echo(f"heading before:     {base:8.2f}°")
    click.echo(f"heading predicted:  {predicted:8.2f}°")
    click.echo(f"heading measured:   {measured:8.2f}° ({T} transitions)")
    if choice is not None:
        click.echo(f"wanted {heading:g}°: residual {choice.residual:+.2f}° (steps of {360 / n:g}°)")
