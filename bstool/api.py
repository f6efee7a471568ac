"""bstool from Python: a small facade over the stages, for notebooks and scripts.

Each function calls the same library code as its command (``bstool simulate``, ``evolve``,
``compile``, ``tokenize``, ``flash``), returns objects instead of printing, and raises the
:mod:`bstool.errors` types (``InputError`` for bad arguments or files, ``SourceError``,
``BuildError``, ``DeviceError``) with a message and a hint. Nothing here prints, exits or
imports MuJoCo before a simulation needs it. Reference: docs/api.md.

    import bstool.api as bst
    ctrl = bst.builtin_controller("nnsin")
    print(bst.simulate(ctrl).distance)
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bstool.controllers import Controller, from_json
from bstool.controllers import load_controller as _load_file
from bstool.errors import InputError
from bstool.evolve.driver import (
    EvolveInterrupted,
    EvolveResult,
    Generation,
    evolve,
    fitness_text,
    resume,
)
from bstool.evolve.engine import GAParams, HistoryRow

if TYPE_CHECKING:
    from bstool.compile import BuildResult
    from bstool.flash import ModuleReport, Progress, Timing
    from bstool.robot import RobotSpec
    from bstool.robot.robotfile import Robot
    from bstool.sim import SimResult
    from bstool.tokenizer import Project

__all__ = [
    "DEFAULT_TRANSITIONS",
    "Controller",
    "EvolveInterrupted",
    "EvolveResult",
    "GAParams",
    "Generation",
    "HistoryRow",
    "builtin_controller",
    "compile",
    "evaluate",
    "evolve",
    "fitness_text",
    "flash",
    "load_controller",
    "load_robot",
    "load_states",
    "resume",
    "simulate",
    "states",
    "tokenize",
    "tokenize_text",
]

#: the paper's MAX_TRANS: transitions played when neither the call nor the controller says
DEFAULT_TRANSITIONS = 30

PathLike = str | os.PathLike[str]
ControllerLike = Controller | PathLike | Mapping[str, Any]


def load_controller(source: ControllerLike) -> Controller:
    """A validated controller from a file path, a ``bstool.controller/1`` dict, or a
    :class:`Controller` (returned as is). ``InputError`` names the bad field."""
    if isinstance(source, Controller):
        return source
    if isinstance(source, Mapping):
        return from_json(dict(source), "controller")
    if isinstance(source, str | os.PathLike):
        return _load_file(source)
    raise InputError(
        f"expected a controller, a path or a dict, got {type(source).__name__}",
        hint="e.g. load_controller('run/best.json')",
    )


def builtin_controller(model: str = "nnsin") -> Controller:
    """The evolved controller of ``model`` shipped with bstool (the commands' default)."""
    from bstool.builtin import builtin_controller as path_of

    return _load_file(path_of(model))


def _transitions(ctrl: Controller, transitions: int | None) -> int:
    if transitions is None:
        return ctrl.max_trans if ctrl.max_trans is not None else DEFAULT_TRANSITIONS
    if isinstance(transitions, bool) or not isinstance(transitions, int) or transitions < 0:
        raise InputError(f"transitions must be an integer >= 0, got {transitions!r}")
    return transitions


def states(
    controller: ControllerLike,
    *,
    transitions: int | None = None,
    failed: Sequence[Any] = (),
    failed_at: Mapping[Any, int] | None = None,
) -> np.ndarray:
    """R^0..R^T as an int array (T+1, n, m), as ``bstool states`` prints it.

    ``transitions`` defaults to the controller's max_trans, else 30. ``failed`` modules
    ("L.M", ModuleId or (leg, module)) keep R^0; ``failed_at`` {module: T0} fail during the run.
    """
    ctrl = load_controller(controller)
    return ctrl.states(_transitions(ctrl, transitions), failed, failed_at=failed_at)


def _spec(legs: int, modules: int, spec: RobotSpec | None, source: Any = None) -> RobotSpec:
    """``spec`` if given, else the robot ``source`` (a controller) was evolved for, else the
    default robot of legs × modules."""
    from bstool.robot import RobotSpec
    from bstool.robot.robotfile import from_record

    if spec is not None:
        return spec
    if not isinstance(source, np.ndarray) and source is not None:
        recorded = load_controller(source).robot
        if recorded is not None:
            return from_record(recorded, "the controller").spec
    return RobotSpec(legs=legs, modules=modules)


def load_robot(path: PathLike) -> Robot:
    """A robot file (``bstool.robot/1``): ``.spec`` is the RobotSpec to pass as ``spec=``,
    ``.box`` its uncertain ranges (or the default box). Raises ``InputError`` naming the key."""
    from bstool.robot import robotfile

    return robotfile.load(path)


def load_states(path: PathLike, *, spec: RobotSpec | None = None) -> np.ndarray:
    """A states file (JSON list of T+1 frames of n lists of m ints), validated for ``spec``
    (default: the 5×6 robot)."""
    from bstool.sim import load_states_file

    return load_states_file(Path(path), _spec(5, 6, spec))


def _sequence(
    source: ControllerLike | np.ndarray,
    transitions: int | None,
    failed: Sequence[Any],
    failed_at: Mapping[Any, int] | None,
) -> np.ndarray:
    if isinstance(source, np.ndarray):
        if failed or failed_at:
            raise InputError(
                "failed= and failed_at= apply to a controller; a states array plays as given",
                hint="give the controller, or hold the failed modules in the array yourself",
            )
        if transitions is not None:
            return source[: transitions + 1]
        return source
    return states(source, transitions=transitions, failed=failed, failed_at=failed_at)


def simulate(
    source: ControllerLike | np.ndarray,
    *,
    transitions: int | None = None,
    failed: Sequence[Any] = (),
    failed_at: Mapping[Any, int] | None = None,
    spec: RobotSpec | None = None,
) -> SimResult:
    """Play a controller (or a (T+1, n, m) states array) on the MuJoCo robot: ``spec`` (e.g.
    ``load_robot(path).spec``), else the robot the controller was evolved for, else the
    default one.

    Returns a ``SimResult``: ``path`` (T+1, 2) disc xy in metres, ``displacement``,
    ``distance`` (eq. 6, metres). Deterministic to the bit.
    """
    from bstool.sim import Simulator

    seq = _sequence(source, transitions, failed, failed_at)
    shape = np.shape(seq)
    legs, modules = (shape[1], shape[2]) if len(shape) == 3 else (5, 6)
    return Simulator(_spec(legs, modules, spec, source)).run(seq)


def evaluate(
    batch: Sequence[ControllerLike | np.ndarray],
    *,
    transitions: int | None = None,
    workers: int | None = None,
    spec: RobotSpec | None = None,
) -> list[SimResult]:
    """Simulate many controllers / states arrays on ``workers`` threads (default: the usable
    CPUs); one ``SimResult`` per item, in order, equal to :func:`simulate`'s."""
    from bstool.evolve.options import check_workers
    from bstool.sim import evaluate_batch

    check_workers(workers)
    seqs = [_sequence(item, transitions, (), None) for item in batch]
    if not seqs:
        return []
    shape = np.shape(seqs[0])
    legs, modules = (shape[1], shape[2]) if len(shape) == 3 else (5, 6)
    return evaluate_batch(_spec(legs, modules, spec, batch[0]), seqs, workers=workers)


def compile(  # the stage's name: bstool.api is used as a namespace
    controller: ControllerLike,
    out: PathLike,
    *,
    calibration: PathLike | None = None,
    period: float | None = None,
    modules: Sequence[str] = (),
    tokenize: bool = True,
    progress: bool = False,
    robot: PathLike | Robot | None = None,
) -> BuildResult:
    """Compile into the build folder ``out`` (replaced as a whole), as ``bstool compile``;
    ``robot``: a robot file or ``load_robot``'s result (default: the controller's robot).

    Returns a ``BuildResult`` (``out_dir``, ``controller_hash``, ``modules``, ``manifest``).
    Raises ``BuildError`` when the controller does not fit, ``InputError`` for bad paths.
    """
    from bstool.compile import compile_controller
    from bstool.compile.build import compile_loaded

    options: dict[str, Any] = {
        "calibration": calibration,
        "period": period,
        "modules": modules,
        "tokenize": tokenize,
        "progress": progress,
        "robot": robot,
    }
    if isinstance(controller, str | os.PathLike):
        return compile_controller(controller, out, **options)
    return compile_loaded(
        load_controller(controller), out, source_name="controller.json", **options
    )


def tokenize(path: PathLike) -> Project:
    """Tokenize a PBASIC 2.5 file (its slot files too): a ``Project`` whose ``slots`` map slot
    numbers to images (``eeprom`` 2048 bytes, ``records``, sizes). ``SourceError`` on errors."""
    from bstool.tokenizer import tokenize_file

    return tokenize_file(path)


def tokenize_text(text: str, *, filename: str = "<source>") -> Project:
    """Tokenize PBASIC source text (``filename`` is used in error messages)."""
    from bstool.tokenizer import tokenize_source

    return tokenize_source(text, filename)


def flash(
    target: PathLike,
    port: str,
    *,
    module: str | None = None,
    slot: int | None = None,
    timing: Timing | None = None,
    progress: Callable[[Progress], None] | None = None,
    log: Callable[[str], None] | None = None,
    listen: bool = True,
) -> ModuleReport:
    """Upload one module of ``target`` (a build folder, a .bsx, or a controller file) through
    ``port`` (a device, ``socket://``, or hil_mock's ``bstwin://NAME``), then check the start-up
    announcement. ``module`` ("L.M") picks it in a build of several. Returns the
    ``ModuleReport`` (``announcement_ok``, ``summary()``); raises ``DeviceError`` subclasses.
    """
    from bstool.compile import compile_controller
    from bstool.flash import flash_module, load_target

    plans = load_target(Path(target), module=module, slot=slot, compiler=compile_controller).modules
    if len(plans) != 1:  # pragma: no cover - load_target asks for a module first
        raise InputError(f"{target} has {len(plans)} modules: choose one with module='L.M'")
    return flash_module(port, plans[0], timing=timing, progress=progress, log=log, listen=listen)
