"""The campaign plan (``bstool.campaign/1``, TOML): which models and seeds to evolve, with which
``bstool evolve`` settings, and which analyses to run on each result (docs/campaign.md).

Every key is checked before any run starts: an unknown key is an :class:`InputError` naming it,
with the closest known key as a suggestion. The evolve settings a plan may hold are not listed
here: the caller passes them (:class:`Setting`, derived from ``bstool evolve``'s options), so an
option evolve gains is a plan key at once.
"""

from __future__ import annotations

import difflib
import os
import tomllib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bstool import fileio
from bstool.controllers.reference import MODELS
from bstool.errors import InputError

FORMAT = "bstool.campaign/1"
PLAN_FILE = "plan.toml"
#: largest plan file read (a plan is a few hundred bytes)
MAX_PLAN_BYTES = 1024 * 1024

TOP_KEYS = ("format", "models", "seeds", "evolve", "analyses")
ANALYSIS_KEYS = (
    "faults",
    "multi-failures",
    "extrapolate",
    "paths",
    "initial-states",
    "sensitivity",
)
#: evolve options that are not settings of a run, with what to do instead
NOT_SETTINGS = {
    "seed": "the seeds are the plan's top-level `seeds` list",
    "out": "each run's folder is DIR/runs/MODEL-sSEED",
    "resume": "running the same campaign again resumes it",
    "force": "a campaign never replaces a run; move the folder away to start it again",
    "workers": "give --workers to bstool campaign",
    "cluster": "give --cluster to bstool campaign",
    "quiet": "give -q to bstool campaign",
}
DEFAULT_EXTRAPOLATE = 120
DEFAULT_INITIAL_K = (1, 2, 5, 10)
DEFAULT_INITIAL_SAMPLES = 20


@dataclass(frozen=True)
class Setting:
    """One ``bstool evolve`` option a plan may set: its plan key (the long option name without
    ``--``), its Python keyword, the TOML value types it takes and a check that returns the
    value as evolve would see it or raises ``ValueError`` with the reason."""

    key: str
    name: str
    types: tuple[type, ...]
    convert: Callable[[Any], Any]
    flag: bool = False  # an on/off option: true in the plan = the flag given


@dataclass(frozen=True)
class InitialStates:
    """§4: distance when ``k`` of the n·m initial states change by ±1, ``samples`` draws per k."""

    k: tuple[int, ...] = DEFAULT_INITIAL_K
    samples: int = DEFAULT_INITIAL_SAMPLES


@dataclass(frozen=True)
class Sensitivity:
    """``bstool sensitivity`` on each run: every uncertain parameter alone at ``points`` values,
    and ``samples`` robots drawn from all ranges at once (seeded)."""

    points: int = 5
    samples: int = 32
    seed: int = 0


@dataclass(frozen=True)
class Analyses:
    faults: bool = False  # Fig. 17: every single module failed
    multi_failures: int = 0  # K = 1..5 failed at once, this many random sets per K (0: off)
    extrapolate: int | None = None  # Fig. 19: transitions (None: off)
    reinit_every: int | None = None  # the remedy's period (None: the runs' MAX_TRANS)
    paths: bool = False  # Fig. 18
    initial_states: InitialStates | None = None  # §4
    sensitivity: Sensitivity | None = None  # physics uncertainty (docs/robot.md)

    def to_json(self) -> dict[str, Any]:
        init = self.initial_states
        return {
            "faults": self.faults,
            "multi-failures": self.multi_failures,
            "extrapolate": self.extrapolate,
            "reinit-every": self.reinit_every,
            "paths": self.paths,
            "initial-states": None
            if init is None
            else {"k": list(init.k), "samples": init.samples},
            "sensitivity": None if self.sensitivity is None else vars(self.sensitivity),
        }


@dataclass(frozen=True)
class RunSpec:
    """One evolve run of the campaign."""

    model: str
    seed: int
    settings: Mapping[str, Any]  # plan key -> value (the model's table merged over [evolve])

    @property
    def name(self) -> str:
        return run_name(self.model, self.seed)


def run_name(model: str, seed: int) -> str:
    return f"{model}-s{seed}"


@dataclass(frozen=True)
class CampaignPlan:
    models: tuple[str, ...]
    seeds: tuple[int, ...]
    evolve: Mapping[str, Any] = field(default_factory=dict)  # [evolve]: key -> value
    per_model: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # [evolve.MODEL]
    analyses: Analyses = field(default_factory=Analyses)

    def settings(self, model: str) -> dict[str, Any]:
        """The evolve settings of ``model``'s runs: its own table over ``[evolve]``."""
        return {**self.evolve, **self.per_model.get(model, {})}

    def runs(self) -> list[RunSpec]:
        """Seed-major: every model of the first seed, then the next seed, so a campaign cut
        short has complete seed sets."""
        return [RunSpec(m, s, self.settings(m)) for s in self.seeds for m in self.models]

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "models": list(self.models),
            "seeds": list(self.seeds),
            "evolve": {**self.evolve, **{m: dict(t) for m, t in self.per_model.items()}},
            "analyses": self.analyses.to_json(),
        }


def _suggest(word: str, known: Iterable[str]) -> str | None:
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f"did you mean {close[0]!r}?" if close else None


def _kind(value: Any) -> str:
    names = {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "a list",
        dict: "a table",
    }
    return names.get(type(value), type(value).__name__)


class _Reader:
    """Errors that name the plan file and the table and key at fault."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, what: str, hint: str | None = None) -> InputError:
        return InputError(f"{self.source}: {where}: {what}", hint=hint)

    def unknown(self, where: str, key: str, known: Iterable[str], extra: str = "") -> InputError:
        known = list(known)
        hint = _suggest(key, known) or f"known keys: {', '.join(known)}{extra}"
        return self.fail(where, f"unknown key {key!r}", hint)

    def integer(self, where: str, value: Any, low: int, high: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(where, f"must be an integer, got {_kind(value)} ({value!r})")
        if value < low or (high is not None and value > high):
            span = f"{low}..{high}" if high is not None else f"at least {low}"
            raise self.fail(where, f"must be {span}, got {value}")
        return value

    def boolean(self, where: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise self.fail(where, f"must be true or false, got {_kind(value)} ({value!r})")
        return value

    def table(self, where: str, value: Any) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, f"must be a table, got {_kind(value)} ({value!r})")
        return value

    def unique_list(self, where: str, value: Any) -> list[Any]:
        if not isinstance(value, list) or not value:
            raise self.fail(where, f"must be a non-empty list, got {value!r}")
        seen: set[Any] = set()
        for item in value:
            if isinstance(item, list | dict):
                raise self.fail(where, f"must be a list of single values, got {value!r}")
            if item in seen and not isinstance(item, bool):
                raise self.fail(where, f"{item!r} is listed twice", "list each once")
            seen.add(item)
        return value


def parse(text: str, settings: Mapping[str, Setting], source: str = PLAN_FILE) -> CampaignPlan:
    """Parse and check a plan; ``settings`` are the evolve options it may set (by plan key)."""
    r = _Reader(source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{source}: not a valid TOML file: {exc}") from None
    for key in data:
        if key not in TOP_KEYS:
            raise r.unknown("top level", key, TOP_KEYS)
    if "format" not in data:
        raise r.fail("top level", f"missing format = {FORMAT!r}", "the first line of a plan")
    if data["format"] != FORMAT:
        raise r.fail("format", f"{data['format']!r} is not {FORMAT!r}")
    for key in ("models", "seeds"):
        if key not in data:
            raise r.fail("top level", f"missing {key} = [...]")
    models = r.unique_list("models", data["models"])
    for m in models:
        if m not in MODELS:
            hint = _suggest(str(m), MODELS) or f"one of: {', '.join(MODELS)}"
            raise r.fail("models", f"unknown model {m!r}", hint)
    seeds = [r.integer("seeds", s, 0) for s in r.unique_list("seeds", data["seeds"])]
    evolve, per_model = _evolve(r, r.table("[evolve]", data.get("evolve", {})), models, settings)
    analyses = _analyses(r, r.table("[analyses]", data.get("analyses", {})))
    return CampaignPlan(tuple(models), tuple(seeds), evolve, per_model, analyses)


def _evolve(
    r: _Reader, table: dict[str, Any], models: list[str], settings: Mapping[str, Setting]
) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    common: dict[str, Any] = {}
    per_model: dict[str, dict[str, Any]] = {}
    for key, value in table.items():
        if key in MODELS:
            if not isinstance(value, dict):
                raise r.fail(f"[evolve] {key}", f"a model's settings go in a table [evolve.{key}]")
            if key not in models:
                raise r.fail(
                    f"[evolve.{key}]",
                    f"{key} is not in models",
                    "add it to models, or remove its table",
                )
            per_model[key] = {
                k: _setting(r, f"[evolve.{key}]", k, v, settings) for k, v in value.items()
            }
        elif isinstance(value, dict) and key not in settings:
            hint = _suggest(key, MODELS) or f"[evolve.MODEL] with MODEL one of: {', '.join(MODELS)}"
            raise r.fail(f"[evolve.{key}]", f"unknown model {key!r}", hint)
        else:
            common[key] = _setting(r, "[evolve]", key, value, settings)
    return common, per_model


def _setting(r: _Reader, where: str, key: str, value: Any, settings: Mapping[str, Setting]) -> Any:
    if key in NOT_SETTINGS:
        raise r.fail(where, f"{key!r} is not a setting of a run", NOT_SETTINGS[key])
    s = settings.get(key)
    if s is None:
        raise r.unknown(where, key, sorted(settings), " (bstool evolve's long options)")
    if not isinstance(value, s.types) or (isinstance(value, bool) and bool not in s.types):
        want = " or ".join(sorted({_kind(t()) for t in s.types}))
        raise r.fail(f"{where} {key}", f"must be {want}, got {_kind(value)} ({value!r})")
    try:
        return s.convert(value)
    except ValueError as exc:
        raise r.fail(f"{where} {key}", str(exc)) from None


def _analyses(r: _Reader, table: dict[str, Any]) -> Analyses:
    for key in table:
        if key not in ANALYSIS_KEYS:
            raise r.unknown("[analyses]", key, ANALYSIS_KEYS)
    where = "[analyses]"
    faults = r.boolean(f"{where} faults", table.get("faults", False))
    paths = r.boolean(f"{where} paths", table.get("paths", False))
    multi = r.integer(f"{where} multi-failures", table.get("multi-failures", 0), 0)
    extrapolate, reinit = _extrapolate(r, table.get("extrapolate", False))
    initial = _initial_states(r, table.get("initial-states", False))
    sensitivity = _sensitivity(r, table.get("sensitivity", False))
    return Analyses(faults, multi, extrapolate, reinit, paths, initial, sensitivity)


def _extrapolate(r: _Reader, value: Any) -> tuple[int | None, int | None]:
    where = "[analyses] extrapolate"
    if isinstance(value, bool):
        return (DEFAULT_EXTRAPOLATE if value else None), None
    table = r.table(where, value)
    for key in table:
        if key not in ("transitions", "reinit-every"):
            raise r.unknown(where, key, ("transitions", "reinit-every"))
    transitions = r.integer(
        f"{where} transitions", table.get("transitions", DEFAULT_EXTRAPOLATE), 2
    )
    reinit = table.get("reinit-every")
    return transitions, None if reinit is None else r.integer(f"{where} reinit-every", reinit, 1)


def _initial_states(r: _Reader, value: Any) -> InitialStates | None:
    where = "[analyses] initial-states"
    if isinstance(value, bool):
        return InitialStates() if value else None
    table = r.table(where, value)
    for key in table:
        if key not in ("k", "samples"):
            raise r.unknown(where, key, ("k", "samples"))
    ks = table.get("k", list(DEFAULT_INITIAL_K))
    if isinstance(ks, int) and not isinstance(ks, bool):
        ks = [ks]
    ks = [r.integer(f"{where} k", k, 1) for k in r.unique_list(f"{where} k", ks)]
    samples = r.integer(f"{where} samples", table.get("samples", DEFAULT_INITIAL_SAMPLES), 1)
    return InitialStates(tuple(ks), samples)


def _sensitivity(r: _Reader, value: Any) -> Sensitivity | None:
    where = "[analyses] sensitivity"
    if isinstance(value, bool):
        return Sensitivity() if value else None
    table = r.table(where, value)
    keys = ("points", "samples", "seed")
    for key in table:
        if key not in keys:
            raise r.unknown(where, key, keys)
    d = Sensitivity()
    return Sensitivity(
        r.integer(f"{where} points", table.get("points", d.points), 2),
        r.integer(f"{where} samples", table.get("samples", d.samples), 1),
        r.integer(f"{where} seed", table.get("seed", d.seed), 0),
    )


def read_text(path: str | os.PathLike[str]) -> str:
    """A plan file's text (UTF-8, a regular file of at most 1 MiB)."""
    data = fileio.read_limited(path, "plan file", MAX_PLAN_BYTES)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"cannot read plan file {path}: not UTF-8 text") from None


def load(path: str | os.PathLike[str], settings: Mapping[str, Setting]) -> CampaignPlan:
    return parse(read_text(path), settings, str(Path(path)))


def differences(a: CampaignPlan, b: CampaignPlan) -> list[str]:
    """What differs between two plans, in words (empty: the same plan)."""
    out = []
    ja, jb = a.to_json(), b.to_json()
    for key in ("models", "seeds"):
        if ja[key] != jb[key]:
            out.append(f"{key} {ja[key]} against {jb[key]}")
    for model in (None, *MODELS):
        sa = a.evolve if model is None else a.per_model.get(model, {})
        sb = b.evolve if model is None else b.per_model.get(model, {})
        where = "[evolve]" if model is None else f"[evolve.{model}]"
        for key in dict.fromkeys([*sa, *sb]):
            if sa.get(key) != sb.get(key):
                out.append(f"{where} {key} {sa.get(key)!r} against {sb.get(key)!r}")
    for key, value in ja["analyses"].items():
        if value != jb["analyses"][key]:
            out.append(f"[analyses] {key} {value!r} against {jb['analyses'][key]!r}")
    return out
