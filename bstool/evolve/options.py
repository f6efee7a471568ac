"""The GA's settings from user options: defaults in one place, checks before any work, and what
a resumed run may change. Used by ``bstool evolve`` and by :func:`bstool.api.evolve` alike, so
both refuse the same things with the same :class:`~bstool.errors.InputError`.

Messages name the command-line flags (``--parasite-k``); each is the keyword of the same name in
the Python API (``parasite_k=``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import secrets
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bstool.controllers.reference import MODELS
from bstool.errors import InputError
from bstool.evolve.engine import GAParams, RunState, default_gens, default_pm
from bstool.evolve.problem import Problem
from bstool.evolve.scoring import ROBUST_MODES, parse_k

#: physics (MuJoCo, eq. 6 distance in metres) or toy (a cheap stand-in, not a distance)
FITNESS_KINDS = ("physics", "toy")
#: --coevolve-faults' parasite population: Q + 1 = 5 runs per host, the budget of --robust, n = 5
DEFAULT_PARASITES = 4

_CELLS = Problem("ca1d").legs * Problem("ca1d").modules  # the robot bstool evolve builds

#: the settings a resumed run keeps (only --gens may be raised)
FIXED_ON_RESUME = (
    "model",
    "pop",
    "pc",
    "pm",
    "transitions",
    "coevol_gens",
    "seed",
    "fitness",
    "robust",
    "coevolve_faults",
    "parasites",
    "parasite_k",
    "stamp_timed",
    "schedule_builds",
    "randomize",
    "robot",
)

#: ``--schedule-builds K``: a stamp-timed candidate is played on K builds of random controllers,
#: its fitness the mean distance (``bstool.sim.timed.ScheduleEnsemble``; K physics runs per
#: candidate); without it, one model averaged over two builds (docs/twin.md "For evolution")
MAX_BUILDS = 64


def default(name: str, model: str | None = None) -> Any:
    """The default of GA option ``name`` (GAParams' field; gens and pm depend on the model)."""
    if name == "gens" and model is not None:
        return default_gens(model)
    if name == "pm" and model is not None:
        return default_pm(model)
    if name == "parasites":
        return DEFAULT_PARASITES
    if name == "fitness":
        return FITNESS_KINDS[0]
    fields: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(GAParams)}
    if name == "parasite_k":
        low, high = fields["parasite_k"]
        return f"{low}..{high}" if low != high else str(low)
    return fields[name]


def default_text(name: str) -> str:
    """The default as --help shows it (model-dependent ones per model)."""
    if name == "gens":
        return f"{default('gens', 'ca1d')}; ca2ddiff: {default('gens', 'ca2ddiff')} outer loops"
    if name == "pm":
        return f"{default('pm', 'ca1d')} CA, {default('pm', 'nnsin')} NN"
    return str(default(name))


def flag(name: str) -> str:
    return "MODEL" if name == "model" else "--" + name.replace("_", "-")


def _int(name: str, value: Any, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise InputError(f"{flag(name)} must be an integer of at least {low}, got {value!r}")
    if high is not None and value > high:
        raise InputError(f"{flag(name)} must be an integer of at most {high}, got {value!r}")
    return value


def _probability(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= 1:
        raise InputError(f"{flag(name)} must be a probability in 0..1, got {value!r}")
    return float(value)


def check_model(model: Any) -> str:
    if model is None:
        raise InputError("missing MODEL", hint=f"one of: {', '.join(MODELS)}")
    if model not in MODELS:
        raise InputError(f"unknown MODEL {model!r}", hint=f"one of: {', '.join(MODELS)}")
    return str(model)


def check_fitness(kind: Any) -> str:
    if kind not in FITNESS_KINDS:
        raise InputError(f"unknown --fitness {kind!r}", hint=f"one of: {', '.join(FITNESS_KINDS)}")
    return str(kind)


def parasite_range(value: Any) -> tuple[int, int]:
    """``--parasite-k`` as "K", "A..B", an int or a (low, high) pair, within the robot."""
    if isinstance(value, str):
        return parse_k(value, _CELLS)
    if isinstance(value, int) and not isinstance(value, bool):
        return parse_k(str(value), _CELLS)
    try:
        low, high = (int(x) for x in value)
    except (TypeError, ValueError):
        raise InputError(
            f"--parasite-k {value!r} is not K, A..B or a (low, high) pair",
            hint='e.g. --parasite-k 1 or --parasite-k "1..2"',
        ) from None
    return parse_k(f"{low}..{high}", _CELLS)


def ga_params(
    model: str,
    *,
    pop: int | None = None,
    gens: int | None = None,
    pc: float | None = None,
    pm: float | None = None,
    transitions: int | None = None,
    coevol_gens: int | None = None,
    seed: int | None = None,
    robust: str | None = None,
    coevolve_faults: bool = False,
    parasites: int | None = None,
    parasite_k: Any = None,
) -> GAParams:
    """Checked GA parameters for a new run; ``None`` means the default (a random 32-bit seed)."""
    model = check_model(model)

    def pick(name: str, value: Any) -> Any:
        return default(name, model) if value is None else value

    if not coevolve_faults:
        for name, value in (("parasites", parasites), ("parasite_k", parasite_k)):
            if value is not None:
                raise InputError(
                    f"{flag(name)} only applies with --coevolve-faults",
                    hint=f"add --coevolve-faults, or drop {flag(name)}",
                )
    elif robust is not None:
        raise InputError(
            "--robust and --coevolve-faults do not combine",
            hint="choose one scoring: rotations (--robust) or failures (--coevolve-faults)",
        )
    if robust is not None and robust not in ROBUST_MODES:
        raise InputError(
            f"unknown --robust mode {robust!r}", hint=f"one of: {', '.join(ROBUST_MODES)}"
        )
    return GAParams(
        pop=_int("pop", pick("pop", pop), 2),
        gens=_int("gens", pick("gens", gens), 1),
        pc=_probability("pc", pick("pc", pc)),
        pm=_probability("pm", pick("pm", pm)),
        transitions=_int("transitions", pick("transitions", transitions), 1),
        coevol_gens=_int("coevol_gens", pick("coevol_gens", coevol_gens), 1),
        seed=secrets.randbits(32) if seed is None else _int("seed", seed, 0),
        robust=robust,
        parasites=_int("parasites", pick("parasites", parasites), 2) if coevolve_faults else 0,
        parasite_k=parasite_range(pick("parasite_k", parasite_k)),
    )


def stamp_timed_settings(
    kind: str, stamp_timed: bool, period: Any, timing: Any = None, builds: Any = None
) -> dict[str, Any]:
    """What a run saves for ``--stamp-timed`` / ``--period`` / ``--timing`` /
    ``--schedule-builds`` (nothing without them). ``timing``: a ``bstool.timing/1`` file; the
    run records its name and sha256 (a resumed run must be given the same file)."""
    if not stamp_timed:
        for name, value in (("period", period), ("timing", timing), ("schedule-builds", builds)):
            if value is not None:
                raise InputError(
                    f"--{name} only applies with --stamp-timed", hint="add --stamp-timed"
                )
        return {}
    if kind != "physics":
        raise InputError(
            f"--stamp-timed needs physics fitness, not --fitness {kind}",
            hint="drop --fitness toy",
        )
    if period is not None and (
        isinstance(period, bool) or not isinstance(period, int | float) or not period > 0
    ):
        raise InputError(f"--period must be a positive number of seconds, got {period!r}")
    out: dict[str, Any] = {"stamp_timed": True, "period": None if period is None else float(period)}
    if builds is not None:
        out["schedule_builds"] = _int("schedule_builds", builds, 1, MAX_BUILDS)
    if timing is not None:
        out["timing"] = timing_record(timing)
    return out


def _check_randomize_typed(
    typed: Mapping[str, Any], saved: Mapping[str, Any], directory: str | os.PathLike[str]
) -> None:
    """On --resume: each randomize option typed must equal the run's own (the others are
    the run's, whatever their defaults are today)."""
    from bstool.evolve.randomize import OPTION_FLAGS

    for key, value in typed.items():
        before = saved.get(key)
        if key == "box" and value != before:
            was = (
                "another box" if before is not None
                else "without --randomize-box (on the robot's own uncertainty)"
            )  # fmt: skip
            raise InputError(
                f"--randomize-box: the file's [uncertain] table is not the box the run in "
                f"{directory} was started with ({was})",
                hint="a resumed run keeps its settings; give the run's own box or none",
            )
        if value != before:
            raise InputError(
                f"{OPTION_FLAGS[key]} is {value!r} but the run in {directory} was started "
                f"with {before!r}",
                hint="a resumed run keeps its settings; only --gens may be raised",
            )


def randomize_settings(
    randomize: bool,
    samples: Any = None,
    score: Any = None,
    validate_every: Any = None,
    validation_samples: Any = None,
    train_timestep: Any = None,
    box: Any = None,
) -> dict[str, Any]:
    """What a run saves for ``--randomize`` and its options (nothing without it); ``box``: a
    robot file (or ``Robot``) whose ``[uncertain]`` table is the box to train on."""
    from bstool.evolve.randomize import DEFAULT_TRAIN_TIMESTEP, OPTION_FLAGS, Randomize

    if not randomize:
        values = (samples, score, validate_every, validation_samples, train_timestep, box)
        for flag, value in zip(OPTION_FLAGS.values(), values, strict=True):
            if value is not None:
                raise InputError(f"{flag} only applies with --randomize", hint="add --randomize")
        return {}
    d = Randomize()
    settings = Randomize(
        samples=d.samples if samples is None else samples,
        score=d.score if score is None else score,
        validate_every=d.validate_every if validate_every is None else validate_every,
        validation_samples=d.validation_samples if validation_samples is None
        else validation_samples,
        train_timestep=DEFAULT_TRAIN_TIMESTEP if train_timestep is None else train_timestep,
        box=None if box is None else box_table(box),
    )  # fmt: skip
    return {"randomize": settings.to_json()}


def box_table(box: Any) -> dict[str, Any]:
    """``--randomize-box``: the ``[uncertain]`` table of a robot file (or of a ``Robot``);
    the robot's values come from ``--robot`` (:func:`check_box_robot`)."""
    loaded = _load_box(box)
    if loaded.uncertain is None or not loaded.uncertain.ranges:
        what = "no" if loaded.uncertain is None else "an empty"
        raise InputError(
            f"--randomize-box: {loaded.source} has {what} [uncertain] table, so there is no "
            "box to draw the robots from",
            hint="give it ranges (`bstool robot` shows the syntax), or drop --randomize-box "
            "to train on the robot's own uncertainty",
        )
    return loaded.uncertain.to_toml_table()


def check_box_robot(box: Any, robot: Any) -> None:
    """Refuse a box file that states robot values other than the run's robot's: a relative
    range (``scale``) is taken around the run's robot, not around the values the box file
    states, so a file that disagrees would train on other robots than its author meant. (A
    ``Robot`` given as the box: only its ranges are used, no values to disagree.)"""
    import tomllib

    if box is None or not isinstance(box, str | os.PathLike):
        return
    table = tomllib.loads(Path(box).read_text(encoding="utf-8"))  # read and checked before
    stated = _load_box(box).spec
    for key in table:
        if key in ("format", "uncertain"):
            continue
        mine, run = getattr(stated, key), getattr(robot.spec, key)
        if mine != run:
            raise InputError(
                f"--randomize-box: {box} sets {key} = {mine!r}, but the run's robot has "
                f"{run!r}: the box's ranges are taken around the run's robot",
                hint="keep only the [uncertain] table in the box file, or give the same "
                "values as the robot (--robot)",
            )


def _load_box(box: Any) -> Any:
    from bstool.robot import robotfile

    if isinstance(box, robotfile.Robot):
        return box
    if not isinstance(box, str | os.PathLike):
        raise InputError(
            f"--randomize-box must be a robot file (a path) or a Robot, got {box!r}",
            hint="write the box as the [uncertain] table of a robot file",
        )
    try:
        return robotfile.load(box)
    except InputError as exc:
        raise InputError(f"--randomize-box: {exc.message}", hint=exc.hint) from None


def robot_settings(robot: Any) -> tuple[Any, dict[str, Any]]:
    """``--robot`` (a robot file, or a ``Robot``): the robot and what the run records (its
    values, not the path; nothing without it)."""
    if robot is None:
        return None, {}
    from bstool.robot import robotfile

    loaded = robot if isinstance(robot, robotfile.Robot) else robotfile.load(robot)
    return loaded, {"robot": loaded.to_json()}


def timing_record(path: str | os.PathLike[str]) -> dict[str, str]:
    """A timing file's name and sha256 (read and checked: a bad file fails before any work)."""
    from bstool import timingfile

    timingfile.load(path)
    try:
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise InputError(f"cannot read timing file {path}: {exc.strerror}") from None
    return {"file": str(path), "sha256": digest}


def resume_timing(
    extra: Mapping[str, Any], timing: Any, directory: str | os.PathLike[str]
) -> str | None:
    """The timing file a resumed run uses: ``timing`` if given, else the one it was started
    with; either must have the sha256 the run recorded (None: the run has none)."""
    saved = extra.get("timing")
    if saved is None:
        if timing is not None:
            raise InputError(f"the run in {directory} was started without --timing",
                             hint="a resumed run keeps its settings")  # fmt: skip
        return None
    path = str(saved["file"] if timing is None else timing)
    try:
        given = timing_record(path)
    except InputError as exc:
        raise InputError(
            f"the run in {directory} was evolved with the timing file {saved['file']}: {exc}",
            hint="give that file with --timing F",
        ) from None
    if given["sha256"] != saved["sha256"]:
        raise InputError(
            f"{path} is not the timing file the run in {directory} was started with "
            f"(sha256 {given['sha256'][:12]}..., not {saved['sha256'][:12]}...)",
            hint="a resumed run keeps its settings; give the same file with --timing F",
        )
    return path


def check_workers(workers: Any) -> int | None:
    return None if workers is None else _int("workers", workers, 1)


def saved_settings(state: RunState, extra: Mapping[str, Any]) -> dict[str, Any]:
    """The settings of a saved run, keyed like the options (absent ones are None)."""
    p = state.params
    return {
        **p.to_json(),
        "model": state.problem.model,
        "robust": p.robust,
        "coevolve_faults": p.coevolve_faults or None,
        "parasites": p.parasites or None,
        "parasite_k": list(p.parasite_k) if p.coevolve_faults else None,
        **extra,
    }


def generations_done(state: RunState) -> int:
    return state.step // (state.total_steps // state.params.gens)


def check_resume(
    state: RunState,
    extra: Mapping[str, Any],
    directory: str | os.PathLike[str],
    given: Mapping[str, Any],
) -> None:
    """Refuse options that differ from the saved run's; apply a raised ``gens`` to ``state``.

    ``given`` holds only the options the user gave (``None`` = not given); ``parasite_k`` may
    be given in any form :func:`parasite_range` takes.
    """
    saved = saved_settings(state, extra)
    for name in FIXED_ON_RESUME:
        value = given.get(name)
        if value is None or value is False:
            continue
        if name == "parasite_k":
            value = list(parasite_range(value))
        if name == "robot":
            value = robot_settings(value)[1]["robot"]
        if name == "randomize" and value is True:
            value = saved.get(name) or True  # the flag alone: kept settings are fine
        if name == "randomize" and isinstance(value, dict) and isinstance(saved.get(name), dict):
            _check_randomize_typed(value, saved[name], directory)
            continue
        before = saved.get(name)
        if value != before:
            raise InputError(
                f"{flag(name)} is {value!r} but the run in {directory} was started with {before!r}"
                if before is not None
                else f"the run in {directory} was started without {flag(name)}",
                hint="a resumed run keeps its settings; only --gens may be raised",
            )
    gens = given.get("gens")
    if gens is not None:
        gens = _int("gens", gens, 1)
        done = generations_done(state)
        if gens < done:
            raise InputError(f"--gens {gens} is less than the {done} generations already done")
        state.params = GAParams(**{**state.params.to_json(), "gens": gens})
