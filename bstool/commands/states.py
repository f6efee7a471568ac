"""``bstool states``: print a controller's reference state sequence as JSON (T+1 frames)."""

from __future__ import annotations

import click

from bstool.controllers import load_controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_failure_time, parse_module

DEFAULT_TRANSITIONS = 30  # the paper's MAX_TRANS, used when the file has no max_trans


@click.command("states")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=0),
    default=None,
    help="Number of transitions T (default: the file's max_trans, else 30).",
)
@click.option(
    "--fail",
    "failed",
    multiple=True,
    metavar="L.M",
    help="A failed module (leg.module, 0 = lead) that keeps its R^0 state; repeatable.",
)
@click.option(
    "--fail-at",
    "fail_at",
    multiple=True,
    metavar="L.M@T",
    help="A module that fails during the run: it follows its rule up to S^T, then holds S^T "
    "(T = 0 is --fail); repeatable.",
)
@click.option(
    "--rejoin",
    "rejoin",
    multiple=True,
    metavar="L.M@T",
    help="A failed module (--fail or --fail-at) that comes back: it still holds its state in "
    "R^T and follows its rule again from R^(T+1), starting from the state it held; repeatable.",
)
@click.option(
    "--held-by",
    "held_by",
    multiple=True,
    metavar="N=L.M@T[..T2]",
    help="CA, a failure per link: neighbour N reads module L.M's state of transition T while "
    "L.M is dead (until its --rejoin), instead of the S^T0 of L.M's --fail-at L.M@T0; T <= T0. "
    "For a power cut between L.M's exchanges of one transition. N=L.M@T..T2: N reads it in "
    "transitions T..T2-1 and L.M's own state from T2 on (a rejoin per link); repeatable.",
)
@click.option(
    "--rejoin-with",
    "rejoin_with",
    multiple=True,
    metavar="L.M@T",
    help="CA: a rejoining module (--rejoin) that comes back with its older state of transition "
    "T < T0 of its --fail-at L.M@T0 (the one a neighbour that went on held for it): it shows "
    "S^T0 in R^T0, S^T from R^(T0+1) to its rejoin, and resumes from S^T; repeatable.",
)
def command(
    controller: str,
    transitions: int | None,
    failed: tuple[str, ...],
    fail_at: tuple[str, ...],
    rejoin: tuple[str, ...],
    held_by: tuple[str, ...],
    rejoin_with: tuple[str, ...],
) -> None:
    """Print CONTROLLER's state sequence R^0..R^T: a JSON array of T+1 frames, each a list of
    n legs of m module states (0..15). Every later stage is checked against this output."""
    ctrl = load_controller(controller)
    if transitions is None:
        transitions = ctrl.max_trans if ctrl.max_trans is not None else DEFAULT_TRANSITIONS
    late = dict(parse_failure_time(f, ctrl.legs, ctrl.modules, "--fail-at") for f in fail_at)
    dead = {ModuleId(*cell) for cell in ctrl.failed_cells(failed)}
    for mid, when in late.items():
        if mid in dead:
            raise InputError(f"module {mid} is both failed from power-up and failing at {when}",
                             hint="give it once: --fail L.M, or --fail-at L.M@T")  # fmt: skip
    back = dict(parse_failure_time(r, ctrl.legs, ctrl.modules, "--rejoin") for r in rejoin)
    held: dict[ModuleId, dict[ModuleId, int | tuple[int, int]]] = {}
    for text in held_by:
        reader, c, span = parse_held_by(text, ctrl.legs, ctrl.modules)
        held.setdefault(c, {})[reader] = span
    older = dict(
        parse_failure_time(r, ctrl.legs, ctrl.modules, "--rejoin-with") for r in rejoin_with
    )
    frames = ctrl.states(
        transitions, failed, failed_at=late, rejoin=back, held=held, rejoin_with=older
    )
    lines = [
        "[" + ",".join("[" + ",".join(str(s) for s in leg) + "]" for leg in frame) + "]"
        for frame in frames.tolist()
    ]
    click.echo("[\n" + ",\n".join(lines) + "\n]")


def parse_held_by(
    text: str, legs: int, modules: int
) -> tuple[ModuleId, ModuleId, int | tuple[int, int]]:
    """``"4.0=0.0@1"``: 4.0 reads 0.0's S^1 while 0.0 is dead -> (reader, module, T);
    ``"4.0=0.0@1..7"``: in transitions 1..6 -> (reader, module, (1, 7))."""
    who, sep, what = text.partition("=")
    where, at, span = what.partition("@")
    first, dots, until = span.partition("..")
    if not sep or not at or (dots and not until.strip().isdigit()):
        raise InputError(
            f"bad --held-by {text!r}: expected N=L.M@T or N=L.M@T..T2, e.g. 4.0=0.0@1 (module "
            "4.0 reads module 0.0's state of transition 1 while 0.0 is dead) or 4.0=0.0@1..7 "
            "(in transitions 1 to 6)"
        )
    mid, when = parse_failure_time(f"{where}@{first}", legs, modules, "--held-by")
    reader = parse_module(who.strip(), legs, modules)
    return reader, mid, (when, int(until)) if dots else when
