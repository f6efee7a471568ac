"""``bstool robot``: the default robot file to edit, or a check of one."""

from __future__ import annotations

import click

from bstool import fileio, outputs
from bstool.robot import robotfile


@click.command("robot")
@click.argument("file", required=False, type=click.Path(dir_okay=False))
@click.option("-o", "--out", type=click.Path(dir_okay=False),
              help="Write the default robot file here instead of printing it.")  # fmt: skip
def command(file: str | None, out: str | None) -> None:
    """Print the default robot file (bstool.robot/1, TOML), every key with its unit and
    source, for you to edit: `bstool robot > my-robot.toml`, then `--robot my-robot.toml` on
    simulate, evolve, compile, twin, sensitivity and the other commands that simulate.

    With FILE: check it and print what differs from the default robot, and the uncertain
    ranges that `evolve --randomize` and `sensitivity` use."""
    if file is not None:
        if out is not None:
            raise click.UsageError("give FILE (to check) or -o OUT (to write), not both")
        robot = robotfile.load(file)
        changes = robot.differences(robotfile.Robot())
        click.echo(f"{file}: a valid {robotfile.FORMAT} robot file")
        values = [c for c in changes if c != "the uncertain ranges"]
        click.echo("differs from the default robot: " + (", ".join(values) or "nothing"))
        where = "its [uncertain] table" if robot.uncertain is not None else "the default box"
        ranges = robot.box.describe() or (
            "none (--randomize refuses an empty table without --randomize-box)"
        )
        click.echo(f"uncertain ({where}): {ranges}")
        return
    text = robotfile.default_text()
    if out is None:
        click.echo(text, nl=False)
        return
    outputs.check_file(out, "robot file")
    fileio.write_text(out, text)
    click.echo(f"wrote {out}", err=True)
