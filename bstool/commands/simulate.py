"""``bstool simulate``: play a controller (or a states file) on the MuJoCo robot.

mujoco is imported only after the GL backend is chosen (``--video`` renders offscreen).
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
import numpy as np

from bstool import fileio, outputs
from bstool.builtin import DEFAULT_MODEL, MODELS
from bstool.commands.robot_option import resolve_robot, robot_option
from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module
from bstool.robot import RobotSpec

if TYPE_CHECKING:
    from bstool.controllers import Controller

DEFAULT_TRANSITIONS = 30  # the paper's MAX_TRANS
EXAMPLE = "example_states.json"


@dataclass
class Source:
    label: str
    states: Any  # np.ndarray (T+1, n, m), validated
    spec: RobotSpec
    failed: list[ModuleId]
    controller: Controller | None = None  # the one the states come from (None: a states file)


@click.command("simulate")
@click.argument("controller", required=False, type=click.Path(dir_okay=False))
@click.option(
    "--states",
    "states_file",
    type=click.Path(dir_okay=False),
    help="A states file (JSON list of T+1 frames of n lists of m ints; '-' = stdin) instead"
    " of a controller.",
)
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=0),
    default=None,
    help="Transitions to run (default: the controller's max_trans, else 30; a states file: all).",
)
@click.option(
    "--fail",
    "failed",
    multiple=True,
    metavar="L.M",
    help="A failed module (leg.module, 0 = lead) held at its R^0 state; repeatable.",
)
@click.option(
    "--transition-time",
    type=float,
    default=None,
    help="Seconds of physics per transition (default: the servo's full-range time × 1.25).",
)
@click.option(
    "--build",
    "build_dir",
    type=click.Path(file_okay=False),
    help="Stamp-timed: move each servo when the build's program on its stamp does (the twin's"
    " timing model, no physics there), with the twin's power-up and join.",
)
@click.option(
    "--stamp-timed",
    is_flag=True,
    help="Stamp-timed on the schedule model `bstool evolve --stamp-timed` scores with (no"
    " build needed): replays such a run's fitness.",
)
@click.option(
    "--period",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="With --stamp-timed: the period of the builds modelled (default: the one the"
    " controller was evolved at, else compile's).",
)
@click.option(
    "--other-builds",
    type=click.IntRange(0, 64),
    default=0,
    help="With --stamp-timed: also play it on N builds of random controllers it was not scored"
    " on, each alone: the spread of builds' timing (for the 2-D CA models, whose phase pattern"
    " is not predictable, their mean is what a new build walks; docs/twin.md).",
)
@click.option(
    "--timing",
    "timing_file",
    type=click.Path(dir_okay=False),
    help="With --build or --stamp-timed: a bstool.timing/1 file (bstool probe), the stamps'"
    " measured timing.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (metres).")
@click.option(
    "--plot", type=click.Path(dir_okay=False), help="Write the disc path as a PNG (paper Fig. 18)."
)
@click.option(
    "--video", type=click.Path(dir_okay=False), help="Render the run offscreen to an MP4 file."
)
@click.option("--view", is_flag=True, help="Watch the run in MuJoCo's viewer (needs a display).")
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Recorded in the output; the simulation itself has no randomness.",
)
@click.option(
    "--model",
    type=click.Choice(MODELS),
    default=DEFAULT_MODEL,
    show_default=True,
    help="Without CONTROLLER: which shipped evolved controller to run.",
)
@click.option(
    "--example", is_flag=True, help="Without CONTROLLER: run the hand-made travelling wave."
)
@robot_option
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def command(
    controller: str | None,
    states_file: str | None,
    transitions: int | None,
    failed: tuple[str, ...],
    transition_time: float | None,
    build_dir: str | None,
    as_json: bool,
    plot: str | None,
    video: str | None,
    view: bool,
    seed: int,
    model: str,
    example: bool,
    quiet: bool,
    timing_file: str | None,
    stamp_timed: bool,
    period: float | None,
    other_builds: int,
    robot: str | None,
) -> None:
    """Run CONTROLLER (a bstool.controller/1 file) or --states FILE on the simulated robot and
    print the disc's displacement and distance (paper eq. 6). Without either, run a shipped
    evolved controller (--model; --example for a hand-made wave)."""
    for what, path in (("plot", plot), ("video", video)):
        if path:
            outputs.check_file(path, what)  # before any simulation
    if timing_file is not None and build_dir is None and not stamp_timed:
        raise InputError(
            "--timing needs --build or --stamp-timed",
            hint="the timing file times the stamps: add --build BUILD or --stamp-timed",
        )
    if period is not None and not stamp_timed:
        raise InputError("--period only applies with --stamp-timed", hint="add --stamp-timed")
    if other_builds and not stamp_timed:
        raise InputError("--other-builds only applies with --stamp-timed", hint="add --stamp-timed")
    given = {"--build": build_dir is not None, "--states": states_file is not None,
             "--video": video is not None, "--view": view,
             "--transition-time": transition_time is not None, "--example": example,
             "--fail": bool(failed)}  # fmt: skip
    if stamp_timed:
        _refuse("--stamp-timed", given, "--stamp-timed needs a controller (or --model) and"
                " models a healthy robot; for a build's own timing, or failed modules, use"
                " --build BUILD")  # fmt: skip
    if build_dir is not None:
        _refuse("--build", {**given, "--build": False, "--fail": False},
                "--build plays the build's own timing; drop the other options")  # fmt: skip
    if video:
        from bstool.sim.gl import configure_headless_gl

        configure_headless_gl()  # before mujoco is imported
    if view:
        from bstool.sim.view import require_display

        require_display()  # fail before simulating

    if build_dir is not None:
        from bstool.commands.simulate_build import load_matching

        build, ctrl_path = load_matching(build_dir, controller)
        controller = ctrl_path
        if robot is not None:  # the build's programs on another robot
            from hil_mock.body import with_robot

            chosen = resolve_robot(
                robot, build.manifest.robot_values, str(build.root), quiet=as_json
            )
            build = with_robot(build, chosen)
    source = _load_source(controller, states_file, transitions, failed, model, example, robot,
                          quiet=as_json or build_dir is not None)  # fmt: skip
    stamp: dict[str, Any] = {}
    if build_dir is not None:
        from bstool.commands.simulate_build import run_build

        result, stamp = run_build(
            build, source.states, source.failed, quiet=quiet, timing_file=timing_file
        )
        timing = stamp["timing"]
    elif stamp_timed:
        from bstool.commands.simulate_model import run_model

        if source.controller is None:
            raise InputError(
                f"--stamp-timed needs a controller file; {source.label} is a states file",
                hint="the schedule model is per controller model: give the controller",
            )
        result, stamp = run_model(
            source.controller,
            source.states,
            source.label,
            period=period,
            timing_file=timing_file,
            other_builds=other_builds,
            spec=source.spec,
        )
        timing = stamp["timing"]
    else:
        from bstool.sim.simulator import Simulator

        sim = Simulator(source.spec, transition_time=transition_time)
        result = _render(sim, source.states, video, quiet) if video else sim.run(source.states)
        timing = f"{sim.transition_time:g} s"

    if plot:
        from bstool.sim.plot import plot_paths

        name = "example" if controller is None and states_file is None else Path(source.label).name
        try:
            plot_paths(plot, [(name, result)], title="Disc displacement")
        except OSError as exc:
            raise InputError(f"cannot write the plot {plot}: {exc}") from None

    out = result.to_json()
    out.update(
        {
            "transitions": result.transitions,
            "transition_time": None if build_dir or stamp_timed else sim.transition_time,
            **{k: v for k, v in stamp.items() if not k.endswith("_text")},
            "source": source.label,
            "failed": [str(m) for m in source.failed],
            "seed": seed,
            "units": "m",
        }
    )
    if as_json:
        click.echo(json.dumps(out))
    else:
        dx, dy = result.displacement
        failed_text = ", ".join(m.label for m in source.failed) or "none"
        click.echo(f"source:       {source.label}")
        click.echo(
            f"run:          {result.transitions} transitions × {timing},"
            f" failed modules: {failed_text}"
        )
        click.echo(f"displacement: dx = {dx:+.4f} m, dy = {dy:+.4f} m")
        click.echo(f"distance:     {result.distance:.4f} m ({result.distance * 100:.2f} cm)")
        for key, label in (("builds_text", "builds:"), ("other_text", "new builds:")):
            if key in stamp:
                click.echo(f"{label:<14}{stamp[key]}")
        if "note" in stamp:
            click.echo(f"note:         {stamp['note']}")
        for name, path in (("plot", plot), ("video", video)):
            if path:
                click.echo(f"{name}:{' ' * (13 - len(name))}{path}")

    if view:
        from bstool.sim.view import view_run

        view_run(sim, source.states)


def _refuse(mode: str, given: dict[str, bool], hint: str) -> None:
    """``mode`` (--build, --stamp-timed) with any of the options ``given`` set is a usage
    error naming them."""
    bad = [flag for flag, on in given.items() if on and flag != mode]
    if bad:
        raise InputError(f"{mode} does not combine with {', '.join(bad)}", hint=hint)


def _load_source(
    controller: str | None,
    states_file: str | None,
    transitions: int | None,
    failed: tuple[str, ...],
    model: str = "nnsin",
    example: bool = False,
    robot: str | None = None,
    *,
    quiet: bool = False,
) -> Source:
    if controller and states_file:
        raise InputError(
            "give either a CONTROLLER file or --states FILE, not both",
            hint="bstool simulate best.json, or bstool simulate --states run.json",
        )
    if controller:
        data = fileio.read_json(controller, "controller file")
        if isinstance(data, list):  # a states file given as the argument
            return _from_states(data, controller, transitions, failed, robot)
        return _from_controller(controller, data, transitions, failed, robot, quiet)
    if states_file == "-":  # e.g. bstool states best.json | bstool simulate --states -
        text = sys.stdin.read(fileio.MAX_JSON_BYTES + 1)
        if len(text) > fileio.MAX_JSON_BYTES:
            raise InputError(
                f"states on <stdin> are larger than {fileio.MAX_JSON_BYTES // 2**20} MiB"
            )
        data = fileio.loads_json(text, "<stdin>", "states")
        return _from_states(data, "<stdin>", transitions, failed, robot)
    if states_file:
        data = fileio.read_json(states_file, "states file")
        return _from_states(data, states_file, transitions, failed, robot)
    if example:
        data = json.loads((resources.files("bstool") / "data" / EXAMPLE).read_text("utf-8"))
        return _from_states(data, f"built-in example ({EXAMPLE})", transitions, failed, robot)
    from bstool.builtin import builtin_controller

    path = builtin_controller(model)
    return _from_controller(str(path), fileio.read_json(path), transitions, failed, robot, quiet)


def _from_states(
    data: Any, label: str, transitions: int | None, failed: tuple[str, ...], robot: str | None
) -> Source:
    from bstool.sim.states import hold_failed, states_from_json

    spec = resolve_robot(robot, quiet=True).spec  # a states file records no robot
    states = states_from_json(data, spec, where=label)
    if transitions is not None:
        if transitions + 1 > len(states):
            raise InputError(
                f"{label} has {len(states)} frames (T = {len(states) - 1}); cannot run"
                f" {transitions} transitions",
                hint=f"use -T {len(states) - 1} or fewer, or give a longer states file",
            )
        states = states[: transitions + 1]
    mids = [parse_module(f, spec.legs, spec.modules) for f in failed]
    return Source(label, hold_failed(states, mids), spec, mids)


def _from_controller(
    path: str,
    data: Any,
    transitions: int | None,
    failed: tuple[str, ...],
    robot: str | None = None,
    quiet: bool = False,
) -> Source:
    if not isinstance(data, dict):
        raise InputError(
            f"{path}: expected a controller (JSON object) or a states file (JSON list),"
            f" got {type(data).__name__}"
        )
    from bstool.controllers import load_controller
    from bstool.sim.states import validate_states

    ctrl = load_controller(path)
    spec = resolve_robot(robot, ctrl.robot, path, quiet=quiet).spec
    mids = [parse_module(f, spec.legs, spec.modules) for f in failed]
    if transitions is None:
        transitions = ctrl.max_trans if ctrl.max_trans is not None else DEFAULT_TRANSITIONS
    states = ctrl.states(transitions, [str(m) for m in mids])
    return Source(path, validate_states(states, spec, where=path), spec, mids, ctrl)


def _render(sim: Any, states: np.ndarray, path: str, quiet: bool) -> Any:
    import sys

    from tqdm import tqdm

    from bstool.sim.video import frame_count, render_video

    total = frame_count(sim, len(states) - 1)
    with tqdm(
        total=total,
        desc="rendering",
        unit="frame",
        file=sys.stderr,
        disable=quiet or not sys.stderr.isatty(),
        leave=False,
    ) as bar:

        def advance(frames: int) -> None:
            bar.update(frames)

        try:
            return render_video(sim, states, path, progress=advance)
        except OSError as exc:
            raise InputError(f"cannot write the video {path}: {exc}") from None
