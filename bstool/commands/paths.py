"""``bstool paths``: several controllers' disc paths on one figure (paper Fig. 18), with the
lateral deviation from the straight line and the sway as numbers."""

from __future__ import annotations

import json

import click

from bstool import outputs
from bstool.commands.robot_option import robot_option
from bstool.commands.robot_option import say_note as _say_note
from bstool.experiments import common, progress
from bstool.experiments.paths import path_shape


@click.command("paths")
@click.argument("controllers", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=1),
    default=None,
    help="Transitions (default: each controller's max_trans, else 30).",
)
@click.option("--plot", type=click.Path(dir_okay=False), help="PNG with every path.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@robot_option
def command(
    controllers: tuple[str, ...],
    transitions: int | None,
    plot: str | None,
    as_json: bool,
    quiet: bool,
    robot: str | None,
) -> None:
    """Simulate each CONTROLLER and compare the paths of the disc. Controllers with the same
    name are told apart by their folders, e.g. ``nnsin (runs)`` and ``nnsin (other)``."""
    if plot:
        outputs.check_file(plot, "plot")
    loaded = [common.load(path, robot) for path in controllers]
    for item in loaded:
        _say_note(item.note, as_json)
    labels = common.unique_labels(controllers)
    from bstool.sim.simulator import SimResult, Simulator

    runs: list[tuple[str, SimResult]] = []
    with progress.bar("paths", len(loaded), quiet=quiet) as advance:
        for label, item in zip(labels, loaded, strict=True):
            T = common.default_transitions(item.controller, transitions)
            runs.append((label, Simulator(item.spec).run(item.controller.states(T))))
            advance(1)
    shapes = {name: path_shape(r.path) for name, r in runs}
    if as_json:
        click.echo(json.dumps({name: s.to_json() for name, s in shapes.items()}))
    else:
        width = max(16, *(len(name) + 2 for name in shapes))
        click.echo(f"{'controller':{width}}{'dist cm':>9}{'len cm':>9}{'max dev':>9}"
                   f"{'rms dev':>9}{'sway':>8}{'heading':>9}")  # fmt: skip
        for name, s in shapes.items():
            click.echo(
                f"{name:{width}}{s.distance * 100:9.2f}{s.length * 100:9.2f}"
                f"{s.max_deviation * 100:9.2f}{s.rms_deviation * 100:9.2f}"
                f"{s.sway * 100:8.2f}{s.heading:8.1f}°"
            )
    if plot:
        from bstool.sim.plot import plot_paths

        plot_paths(plot, runs, title="Disc paths")
