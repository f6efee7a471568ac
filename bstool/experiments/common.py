"""What the experiment commands share: loading a controller with its robot, and an evaluator."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bstool.controllers import Controller, load_controller
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot, resolve


@dataclass
class Loaded:
    path: str
    controller: Controller
    spec: RobotSpec
    robot: Robot | None = None  # the robot resolved for it (spec is its nominal values)
    note: str | None = None  # --robot differs from the robot it was evolved on

    @property
    def name(self) -> str:
        return base_label(self.path)


def load(path: str, robot: str | Robot | None = None) -> Loaded:
    """A controller and the robot to run it on: ``robot`` (``--robot``) if given, else the one
    it was evolved for (recorded in it), else the default."""
    controller = load_controller(path)
    chosen, note = resolve(robot, controller.robot, what=path)
    return Loaded(path, controller, chosen.spec, chosen, note)


def default_transitions(controller: Controller, given: int | None) -> int:
    """-T if given, else the controller's MAX_TRANS, else the paper's 30."""
    if given is not None:
        return given
    return controller.max_trans or 30


def base_label(path: str | Path) -> str:
    """A run's folder name for ``RUN/best.json``, else the file's stem."""
    p = Path(path)
    return p.parent.name if p.name == "best.json" and p.parent.name else p.stem


def unique_labels(paths: Sequence[str | Path], base: Sequence[str] | None = None) -> list[str]:
    """One label per input, all different, each saying where it came from.

    Inputs whose base labels clash get the shortest run of parent folders that tells them
    apart (``nnsin (runs)``, ``nnsin (other)``); the same file given twice gets ``#2``, ``#3``.
    """
    names = list(base) if base is not None else [base_label(p) for p in paths]
    parts = [Path(p).resolve().parent.parts for p in paths]
    labels = list(names)
    for name in set(names):
        idx = [i for i, n in enumerate(names) if n == name]
        if len({Path(paths[i]).resolve() for i in idx}) < 2:
            continue  # one file given several times: numbered below
        depth = 1
        while True:
            tails = {i: _tail(parts[i], depth, Path(paths[i])) for i in idx}
            files = {Path(paths[i]).resolve() for i in idx}
            distinct = len(set(tails.values())) == len(files)
            if distinct or all(depth >= len(parts[i]) for i in idx):
                break
            depth += 1
        for i in idx:
            labels[i] = f"{name} ({tails[i]})"
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):  # the very same file more than once
        seen[label] = seen.get(label, 0) + 1
        if seen[label] > 1:
            labels[i] = f"{label} #{seen[label]}"
    return labels


def _tail(parts: tuple[str, ...], depth: int, path: Path) -> str:
    """The last ``depth`` parent folders (above a run folder for best.json files)."""
    skip = 1 if path.name == "best.json" else 0
    chosen = parts[max(0, len(parts) - skip - depth) : len(parts) - skip]
    return "/".join(chosen) if chosen else "/"
