"""The campaign plan (bstool.campaign/1): the shipped plans parse, every bad key or value is one
InputError naming it (before any run), and a model's table merges over [evolve]."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.campaign import plan as cp
from bstool.campaign.runner import build_plan, keywords
from bstool.commands.campaign import evolve_settings
from bstool.controllers.reference import MODELS
from bstool.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = evolve_settings()
HEAD = 'format = "bstool.campaign/1"\nmodels = ["nnsin", "ca1d"]\nseeds = [1, 2]\n'


def parse(text: str) -> cp.CampaignPlan:
    return cp.parse(text, SETTINGS, "p.toml")


def test_the_settings_are_evolves_options_less_the_run_options() -> None:
    assert {
        "pop",
        "gens",
        "pc",
        "pm",
        "transitions",
        "coevol-gens",
        "fitness",
        "stamp-timed",
        "period",
        "schedule-builds",
        "robust",
        "coevolve-faults",
        "parasites",
        "parasite-k",
        "timing",
        "robot",
        "randomize",
        "randomize-samples",
        "randomize-box",
    } <= set(SETTINGS)
    assert not {"out", "resume", "force", "workers", "cluster", "quiet", "seed"} & set(SETTINGS)


def test_every_setting_reaches_the_driver() -> None:
    """Each of evolve's options is a keyword of options.ga_params or driver.plan_new, which
    the campaign passes it to (an option evolve gains that neither takes fails here)."""
    from bstool.campaign import runner

    taken = runner._GA_KEYWORDS | runner._PLAN_KEYWORDS
    assert [k for k, s in SETTINGS.items() if s.name not in taken] == []


def test_the_shipped_plans() -> None:
    paper = (ROOT / "examples" / "paper.toml").read_text()
    plan = parse(paper)
    assert plan.models == ("nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff")
    assert plan.seeds == (1, 2, 3, 4, 5)
    assert plan.settings("nnsin") == {"pop": 50, "gens": 100}
    assert plan.settings("ca2ddiff") == {"pop": 50, "gens": 3, "coevol-gens": 20}
    a = plan.analyses
    assert (a.faults, a.multi_failures, a.extrapolate, a.paths) == (True, 20, 120, True)
    assert a.initial_states == cp.InitialStates((1, 2, 5, 10), 20)
    assert a.sensitivity is not None
    small = parse((ROOT / "examples" / "campaign-small.toml").read_text())
    assert len(small.seeds) == 2 and len(small.models) >= 2
    randomized = parse((ROOT / "examples" / "paper-randomized.toml").read_text())
    assert randomized.models == plan.models and randomized.seeds == (1, 2)
    assert randomized.settings("nnsin") == {
        "pop": 50, "gens": 100, "randomize": True, "randomize-samples": 4,
    }  # fmt: skip


def test_the_paper_plan_is_the_campaigns() -> None:
    """examples/paper.toml is campaigns/paper/plan.toml (where that folder is present)."""
    running = ROOT / "campaigns" / "paper" / "plan.toml"
    if not running.exists():
        pytest.skip("no campaigns/paper here")
    assert running.read_bytes() == (ROOT / "examples" / "paper.toml").read_bytes()


def test_seed_major_order() -> None:
    plan = parse(HEAD)
    assert [r.name for r in plan.runs()] == ["nnsin-s1", "ca1d-s1", "nnsin-s2", "ca1d-s2"]


@pytest.mark.parametrize(
    ("text", "message", "hint"),
    [
        (HEAD + "[evolve]\npopp = 4\n", "[evolve]: unknown key 'popp'", "did you mean 'pop'?"),
        (HEAD + "[evolve]\nseed = 4\n", "'seed' is not a setting of a run", "seeds"),
        (HEAD + "[evolve]\nworkers = 2\n", "'workers' is not a setting", "--workers"),
        (HEAD + "[evolve]\npop = 1\n", "[evolve] pop: 1 is not in the range x>=2", None),
        (HEAD + "[evolve]\npop = 4.5\n", "[evolve] pop: must be an integer, got a number", None),
        (HEAD + "[evolve]\npop = true\n", "pop: must be an integer, got a boolean", None),
        (HEAD + "[evolve]\npc = 'high'\n", "pc: must be a number or an integer", None),
        (HEAD + "[evolve]\nfitness = 'toys'\n", "fitness: 'toys' is not one of", None),
        (HEAD + "[evolve]\nstamp-timed = 1\n", "stamp-timed: must be a boolean", None),
        (HEAD + "[evolve.ca1dd]\npop = 4\n", "[evolve.ca1dd]: unknown model",
         "did you mean 'ca1d'?"),
        (HEAD + "[evolve.nnsig]\npop = 4\n", "nnsig is not in models", "add it to models"),
        (HEAD + "[evolve.ca1d]\ngen = 4\n", "[evolve.ca1d]: unknown key 'gen'",
         "did you mean 'gens'?"),
        (HEAD + "[analyses]\nfault = true\n", "[analyses]: unknown key 'fault'",
         "did you mean 'faults'?"),
        (HEAD + "[analyses]\nfaults = 1\n", "[analyses] faults: must be true or false", None),
        (HEAD + "[analyses]\nmulti-failures = -1\n", "multi-failures: must be at least 0", None),
        (HEAD + "[analyses]\nextrapolate = { transition = 9 }\n", "unknown key 'transition'",
         "did you mean 'transitions'?"),
        (HEAD + "[analyses]\ninitial-states = { k = [1, 1] }\n", "1 is listed twice", None),
        (HEAD + "[analyses]\nsensitivity = 3\n", "sensitivity: must be a table", None),
        (HEAD + "[analyses]\nsensitivity = { sample = 3 }\n", "unknown key 'sample'",
         "did you mean 'samples'?"),
        (HEAD + "[analyses]\nsensitivity = { points = 1 }\n", "points: must be at least 2", None),
        (HEAD + "[evolv]\npop = 4\n", "top level: unknown key 'evolv'",
         "did you mean 'evolve'?"),
        ('models = ["nnsin"]\nseeds = [1]\n', "missing format", None),
        ('format = "bstool.campaign/2"\nmodels = ["nnsin"]\nseeds = [1]\n', "is not", None),
        ('format = "bstool.campaign/1"\nmodels = ["nnsinn"]\nseeds = [1]\n',
         "unknown model 'nnsinn'", "did you mean 'nnsin'?"),
        ('format = "bstool.campaign/1"\nmodels = ["nnsin", "nnsin"]\nseeds = [1]\n',
         "'nnsin' is listed twice", None),
        ('format = "bstool.campaign/1"\nmodels = ["nnsin"]\nseeds = [1, 2, 1]\n',
         "1 is listed twice", None),
        ('format = "bstool.campaign/1"\nmodels = ["nnsin"]\nseeds = [-1]\n',
         "seeds: must be at least 0", None),
        ('format = "bstool.campaign/1"\nmodels = []\nseeds = [1]\n', "non-empty list", None),
        ('format = "bstool.campaign/1"\nmodels = [["nnsin"]]\nseeds = [1]\n',
         "list of single values", None),
        ('format = "bstool.campaign/1"\nmodels = ["nnsin"]\n', "missing seeds", None),
        ("format = \n", "not a valid TOML file", None),
    ],
)  # fmt: skip
def test_bad_plans(text: str, message: str, hint: str | None) -> None:
    with pytest.raises(InputError) as err:
        parse(text)
    assert message in str(err.value) and str(err.value).startswith("p.toml: ")
    if hint is not None:
        assert err.value.hint is not None and hint in err.value.hint


def test_the_drivers_checks_run_on_each_model() -> None:
    """Combinations only the driver knows are refused before any run, naming the run."""
    from bstool.campaign.runner import check_runs

    plan = parse(HEAD + "[evolve]\nperiod = 0.5\n")
    with pytest.raises(InputError, match="nnsin-s1: --period only applies with --stamp-timed"):
        check_runs(Path("/nonexistent"), plan, SETTINGS)


def test_settings_reach_the_driver() -> None:
    plan = parse(HEAD + "[evolve]\npop = 7\nfitness = 'toy'\ncoevol-gens = 4\n")
    spec = plan.runs()[0]
    assert keywords(spec, SETTINGS) == ({"pop": 7, "coevol_gens": 4}, {"fitness": "toy"})
    p = build_plan(spec, SETTINGS, None)
    assert (p.state.params.pop, p.state.params.seed, p.fitness) == (7, 1, "toy")


def test_differences() -> None:
    a = parse(HEAD + "[evolve]\npop = 7\n")
    b = parse(HEAD.replace("[1, 2]", "[1, 3]") + "[evolve]\npop = 8\n[analyses]\npaths = true\n")
    assert cp.differences(a, a) == []
    diff = cp.differences(a, b)
    assert "seeds [1, 2] against [1, 3]" in diff
    assert "[evolve] pop 7 against 8" in diff
    assert "[analyses] paths False against True" in diff


# -- merging: a property over random plans -----------------------------------------------

VALUES: dict[str, Any] = {
    "pop": st.integers(2, 200),
    "gens": st.integers(1, 500),
    "pc": st.floats(0, 1, allow_nan=False),
    "transitions": st.integers(1, 60),
    "fitness": st.sampled_from(["physics", "toy"]),
    "coevolve-faults": st.booleans(),
}


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


tables = st.dictionaries(st.sampled_from(sorted(VALUES)), st.none()).flatmap(
    lambda keys: st.fixed_dictionaries({k: VALUES[k] for k in keys})
)


@settings(max_examples=60, deadline=None)
@given(
    models=st.lists(st.sampled_from(MODELS), min_size=1, max_size=5, unique=True),
    seeds=st.lists(st.integers(0, 2**32), min_size=1, max_size=4, unique=True),
    common=tables,
    own=st.dictionaries(st.sampled_from(MODELS), tables, max_size=3),
)
def test_a_models_table_overrides_evolve(
    models: list[str], seeds: list[int], common: dict[str, Any], own: dict[str, Any]
) -> None:
    own = {m: t for m, t in own.items() if m in models}
    lines = [f'format = "{cp.FORMAT}"', f"models = {models!r}".replace("'", '"'),
             f"seeds = {seeds!r}", "[evolve]"]  # fmt: skip
    lines += [f"{k} = {_toml(v)}" for k, v in common.items()]
    for m, t in own.items():
        lines += [f"[evolve.{m}]", *(f"{k} = {_toml(v)}" for k, v in t.items())]
    plan = parse("\n".join(lines) + "\n")
    assert plan.models == tuple(models) and plan.seeds == tuple(seeds)
    for m in models:
        assert plan.settings(m) == {**common, **own.get(m, {})}
    assert [(r.model, r.seed) for r in plan.runs()] == [(m, s) for s in seeds for m in models]
    assert cp.differences(plan, parse("\n".join(lines) + "\n")) == []
