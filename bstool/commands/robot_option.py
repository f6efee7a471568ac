"""``--robot FILE``, the same on every command that simulates, evolves or compiles: the option,
and the robot it resolves to (``--robot`` > the robot its input recorded > the default)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

from bstool.robot.robotfile import Robot, resolve

F = TypeVar("F", bound=Callable[..., Any])

HELP = (
    "A robot file (bstool.robot/1; `bstool robot` prints the default one to edit). Default: "
    "the robot the input was evolved or compiled for (recorded in it), else the default robot."
)


def robot_option(func: F) -> F:
    """The ``--robot FILE`` option (parameter ``robot``)."""
    return click.option("--robot", type=click.Path(dir_okay=False), metavar="FILE",
                        help=HELP)(func)  # fmt: skip


def resolve_robot(given: str | None, recorded: Any = None, what: str = "", *,
                  quiet: bool = False) -> Robot:  # fmt: skip
    """The robot to use; says in one line (stderr) when ``--robot`` differs from the recorded
    one (unless ``quiet``)."""
    robot, note = resolve(given, recorded, what=what)
    if note and not quiet:
        click.echo(note, err=True)
    return robot


def say_note(note: str | None, quiet: bool = False) -> None:
    """Print a robot note (``--robot`` differs from the recorded robot) on stderr."""
    if note and not quiet:
        click.echo(note, err=True)
