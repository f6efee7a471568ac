"""The paper's claims, each tested on a campaign's runs: the metric per run, its mean with a
95 % bootstrap interval per model, a two-sided Mann–Whitney U test where the paper compares two
models (or groups of models), and a verdict by the rules of :mod:`bstool.campaign.stats`
(written down in docs/campaign.md).

A claim whose models or analyses are not in the plan is left out, and says which.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bstool.campaign import stats
from bstool.experiments import gait

NN = ("nnsin", "nnsig")
CA = ("ca1d", "ca2dsing", "ca2ddiff")
NOT_TESTED = "not tested"
#: "comparable" (CA2dSing and CA1d, §3.3): the interval of the difference of the means within
#: ±10 % of CA1d's mean; the paper gives no number, 10 % is about a seed's spread of d_30
SIMILAR_FRACTION = 0.10
#: CA1d's failures "fairly distributed" along the leg: lead and other modules' mean M_D within
#: ±10 points of each other
SIMILAR_MD_POINTS = 10.0


@dataclass
class RunData:
    """What the claims read of one finished run."""

    name: str
    model: str
    seed: int
    fitness: float | None
    history: list[Any]  # HistoryRow
    results: dict[str, dict[str, Any]]  # analysis name -> result
    states: np.ndarray  # (T+1, n, m) of its best controller
    transitions: int


Metric = Callable[[RunData], float | None]


@dataclass
class Row:
    label: str
    a: stats.Interval
    b: stats.Interval | None
    test: stats.Test | None
    verdict: str
    difference: stats.Interval | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "label": self.label,
            "a": self.a.to_json(),
            "b": None if self.b is None else self.b.to_json(),
            "test": None if self.test is None else self.test.to_json(),
            "difference": None if self.difference is None else self.difference.to_json(),
            "verdict": self.verdict,
        }


def shown_verdict(claim: Mapping[str, Any]) -> str:
    """A claim's verdict (its JSON) as a table shows it: "not tested: why" when it was not."""
    return f"{NOT_TESTED}: {claim['missing']}" if claim.get("missing") else str(claim["verdict"])


@dataclass
class Claim:
    key: str
    where: str  # the paper's section / figure
    paper: str  # what the paper says
    metric: str  # what is measured here, with its unit
    rows: list[Row] = field(default_factory=list)
    scale: float = 1.0  # display: value × scale
    digits: int = 1
    rule: str = ""
    verdict: str = stats.UNCLEAR
    missing: str | None = None  # why the claim could not be tested

    @property
    def shown(self) -> str:
        """The verdict as a table shows it."""
        return shown_verdict({"verdict": self.verdict, "missing": self.missing})

    def to_json(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "where": self.where,
            "paper": self.paper,
            "metric": self.metric,
            "rule": self.rule,
            "scale": self.scale,
            "digits": self.digits,
            "rows": [r.to_json() for r in self.rows],
            "verdict": self.verdict,
            "missing": self.missing,
        }


# -- metrics -------------------------------------------------------------------------------


def lookup(r: RunData, analysis: str, *path: Any) -> Any:
    value: Any = r.results.get(analysis)
    for p in path:
        if value is None:
            return None
        value = value[p] if isinstance(value, list) else value.get(p)
    return value


def fitness(r: RunData) -> float | None:
    return r.fitness


def distance(r: RunData) -> float | None:
    return lookup(r, "base", "distance")


def max_deviation(r: RunData) -> float | None:
    return lookup(r, "base", "shape", "max_deviation")


def sway(r: RunData) -> float | None:
    return lookup(r, "base", "shape", "sway")


def _mobility(r: RunData) -> np.ndarray | None:
    table = lookup(r, "faults", "mobility")
    if table is None:
        return None
    return np.array([[np.nan if x is None else x for x in row] for row in table], dtype=float)


def _nanmean(x: np.ndarray) -> float | None:
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def mean_mobility(r: RunData) -> float | None:
    md = _mobility(r)
    return None if md is None else _nanmean(md.ravel())


def lead_mobility(r: RunData) -> float | None:
    md = _mobility(r)
    return None if md is None else _nanmean(md[:, 0])


def other_mobility(r: RunData) -> float | None:
    md = _mobility(r)
    return None if md is None else _nanmean(md[:, 1:].ravel())


def keep(percent: int) -> Metric:
    key = "keep_80" if percent == 80 else "keep_100"
    return lambda r: lookup(r, "faults", key)


def fitness_gain(r: RunData) -> float | None:
    """Mean fitness of the population in the last generation minus the first (ca2ddiff: the
    last and first steps of its co-evolution, whichever population)."""
    rows = [h for h in r.history if h.population != "parasite"]
    return None if len(rows) < 2 else float(rows[-1].mean - rows[0].mean)


def _curve(r: RunData, which: str) -> np.ndarray | None:
    c = lookup(r, "extrapolate", which)
    return None if c is None else np.asarray(c, dtype=float)


def beyond_ratio(which: str) -> Metric:
    """Distance at the end of the extrapolation over the distance at MAX_TRANS, minus 1."""

    def metric(r: RunData) -> float | None:
        c = _curve(r, which)
        if c is None or len(c) <= r.transitions or c[r.transitions] <= 0:
            return None
        return float(c[-1] / c[r.transitions] - 1.0)

    return metric


def reinit_gain(r: RunData) -> float | None:
    plain, reinit = _curve(r, "plain"), _curve(r, "reinit")
    if plain is None or reinit is None or len(plain) <= r.transitions or plain[r.transitions] <= 0:
        return None
    return float((reinit[-1] - plain[-1]) / plain[r.transitions])


def peak_at(r: RunData) -> float | None:
    c = _curve(r, "plain")
    return None if c is None else float(np.argmax(c))


def kept(k: int) -> Metric:
    return lambda r: lookup(r, "initial-states", "k", str(k), "mean_kept")


def uncertain_kept(r: RunData) -> float | None:
    """``bstool sensitivity``'s joint sample: mean distance over the nominal one."""
    return lookup(r, "sensitivity", "kept")


def box_mean(r: RunData) -> float | None:
    """``bstool sensitivity``'s joint sample: the mean distance over the random robots (m)."""
    return lookup(r, "sensitivity", "mean")


def clustered(r: RunData) -> float | None:
    return gait.clustered_fraction(r.states)


# -- building rows -------------------------------------------------------------------------

Runs = Mapping[str, Sequence[RunData]]


def values(runs: Runs, models: Sequence[str], metric: Metric) -> list[float | None]:
    return [metric(r) for m in models for r in runs.get(m, ())]


def _name(models: Sequence[str]) -> str:
    """A model, or a group: "NN (nnsin, nnsig)" (the models of it that have runs)."""
    if len(models) == 1:
        return models[0]
    group = "NN" if set(models) <= set(NN) else "CA" if set(models) <= set(CA) else ""
    return f"{group} ({', '.join(models)})" if group else "+".join(models)


def compare(
    runs: Runs,
    a: Sequence[str],
    b: Sequence[str],
    metric: Metric,
    rule: str,
    margin: float | None = None,
) -> Row:
    """A row "a <rule> b": greater, smaller or similar (within ``margin``)."""
    va, vb = values(runs, a, metric), values(runs, b, metric)
    test = stats.mann_whitney(va, vb)
    diff = stats.difference_interval(va, vb)
    if rule == "greater":
        verdict = stats.greater(test)
    elif rule == "smaller":
        verdict = stats.smaller(test)
    else:
        verdict = stats.similar(test, diff, margin or 0.0)
    return Row(
        f"{_name(a)} vs {_name(b)}",
        stats.mean_interval(va),
        stats.mean_interval(vb),
        test,
        verdict,
        diff,
    )


def estimate(
    runs: Runs, models: Sequence[str], metric: Metric, rule: str, value: float = 0.0
) -> Row:
    """A row on one model (or group): its interval against 0 (positive / negative) or
    against the paper's figure (matches)."""
    iv = stats.mean_interval(values(runs, models, metric))
    verdict = {"positive": stats.positive, "negative": stats.negative}.get(rule)
    v = verdict(iv) if verdict else stats.matches(iv, value)
    return Row(_name(models), iv, None, None, v)


def _finish(claim: Claim) -> Claim:
    claim.verdict = stats.combined([r.verdict for r in claim.rows])
    return claim


GREATER = "holds when p < 0.05 with the first larger; does not hold when p < 0.05 the other way"
SMALLER = "holds when p < 0.05 with the first smaller; does not hold when p < 0.05 the other way"


class Need(Protocol):
    def __call__(
        self, claim: Claim, models: Sequence[str], analysis: str | None = None
    ) -> bool: ...


def _checker(
    out: list[Claim], have: Sequence[str], analyses: set[str], always: str | None = None
) -> Need:
    """``need(claim, models[, analysis])``: appends the claim to ``out``; False (the claim
    marked not tested, saying why) when a model has no finished run or the plan lacks the
    claim's analysis or ``always`` (an analysis every claim needs)."""

    def need(claim: Claim, models: Sequence[str], analysis: str | None = None) -> bool:
        lacking = [m for m in models if m not in have]
        absent = [a for a in (always, analysis) if a is not None and a not in analyses]
        if absent:
            claim.missing = f"the plan has no [analyses] {absent[0]}"
        elif lacking:
            claim.missing = f"no finished run of {', '.join(lacking)}"
        if claim.missing is not None:
            claim.verdict = NOT_TESTED
        out.append(claim)
        return claim.missing is None

    return need


def evaluate(runs: Runs, plan_models: Sequence[str], analyses: set[str]) -> list[Claim]:
    """Every claim the runs can test, in the paper's order."""
    have = [m for m in plan_models if runs.get(m)]
    nn, ca = [m for m in NN if m in have], [m for m in CA if m in have]
    both = (*nn[:1], *ca[:1]) if nn and ca else (*NN, *CA)  # a model of each group at least
    out: list[Claim] = []

    need = _checker(out, have, analyses)
    c = Claim(
        "fitness-rises",
        "§3.2.4, Figs. 7, 9, 15, 16",
        "the average fitness of the population increases with the generations",
        "population mean fitness, last generation minus first (cm)",
        scale=100,
        rule="per model: holds when the 95 % interval is above 0",
    )
    if need(c, have[:1]):
        c.rows = [estimate(runs, [m], fitness_gain, "positive") for m in have]
        _finish(c)
    _ranking(runs, have, need, fitness, "best fitness, best.json (cm)")
    c = Claim(
        "nn-tolerate-failures",
        "§5.1, Fig. 17",
        "the NN models handle single module failures better than the CA models",
        "mean M_D over the 30 single failures (%)",
        rule=GREATER,
    )
    if need(c, both, "faults"):
        c.rows = [compare(runs, nn, ca, mean_mobility, "greater")]
        _finish(c)
    c = Claim(
        "fig17-counts",
        "§5.1, Fig. 17",
        "15 single failures keep ≥ 80 % of the mobility "
        "for NNsig and 8 for NNsin; 6 keep 100 % for NNsin",
        "single failures (of 30) keeping ≥ 80 % / 100 % of the healthy distance",
        rule="holds when the paper's count lies in the 95 % interval; the NNsig-NNsin "
        "order by the U test",
    )
    if need(c, NN, "faults"):
        c.rows = [
            estimate(runs, ["nnsig"], keep(80), "matches", 15),
            estimate(runs, ["nnsin"], keep(80), "matches", 8),
            estimate(runs, ["nnsin"], keep(100), "matches", 6),
            compare(runs, ["nnsig"], ["nnsin"], keep(80), "greater"),
        ]
        c.rows[0].label, c.rows[1].label = "nnsig ≥ 80 % (paper 15)", "nnsin ≥ 80 % (paper 8)"
        c.rows[2].label = "nnsin 100 % (paper 6)"
        c.rows[3].label = "nnsig vs nnsin, ≥ 80 %"
        _finish(c)
    c = Claim(
        "lead-failures-hurt-most",
        "§5.1, Fig. 17",
        "a failed lead module hurts most in the 2-D CA and the NN models; in CA1d the "
        "loss is spread evenly along the leg",
        "mean M_D of the 5 lead failures against the 25 others (%)",
        rule=SMALLER + f"; CA1d: holds when the interval of the difference lies within "
        f"±{SIMILAR_MD_POINTS:.0f} points",
    )
    if need(c, have[:1], "faults"):
        for m in have:
            va, vb = values(runs, [m], lead_mobility), values(runs, [m], other_mobility)
            test = stats.mann_whitney(va, vb)
            diff = stats.difference_interval(va, vb)
            verdict = (
                stats.similar(test, diff, SIMILAR_MD_POINTS) if m == "ca1d" else stats.smaller(test)
            )
            label = f"{m}: leads vs others" + (" (paper: alike)" if m == "ca1d" else "")
            c.rows.append(
                Row(label, stats.mean_interval(va), stats.mean_interval(vb), test, verdict, diff)
            )
        _finish(c)
    c = Claim(
        "ca2ddiff-most-resilient",
        "§5.1",
        "CA2dDiff is the most resilient CA model",
        "mean M_D over the 30 single failures (%)",
        rule=GREATER,
    )
    if need(c, CA, "faults"):
        c.rows = [compare(runs, ["ca2ddiff"], [m], mean_mobility, "greater") for m in CA[:2]]
        _finish(c)
    _slowest(runs, have, need, distance, "d_30, the healthy run's distance (cm)")
    for key, paper, metric, what, scale, digits in (
        (
            "nnsig-straightest",
            "NNsig deviates least from the straight start-to-end line",
            max_deviation,
            "largest lateral deviation over MAX_TRANS (cm)",
            100,
            1,
        ),
        (
            "nnsig-smoothest",
            "NNsig moves the most smoothly",
            sway,
            "sway: mean sideways step per transition (cm)",
            100,
            2,
        ),
    ):
        c = Claim(key, "§5.2, Fig. 18", paper, what, scale=scale, digits=digits, rule=SMALLER)
        if need(c, ("nnsig",)):
            c.rows = [
                compare(runs, ["nnsig"], [m], metric, "smaller") for m in have if m != "nnsig"
            ]
            _finish(c)
    c = Claim(
        "ca-stall-beyond-max-trans",
        "§5.2, Fig. 19",
        "the CA models peak around 30 transitions and then degrade (cyclic behaviour)",
        "d_end / d_30 − 1 (the distance at the extrapolation's end against MAX_TRANS)",
        digits=2,
        rule="per model: holds when the 95 % interval is below 0",
    )
    if need(c, [m for m in CA if m in have][:1], "extrapolate"):
        c.rows = [estimate(runs, [m], beyond_ratio("plain"), "negative") for m in CA if m in have]
        _finish(c)
    c = Claim(
        "nn-progress-beyond-max-trans",
        "§5.2, Fig. 19",
        "the NN models go on making progress after MAX_TRANS",
        "d_end / d_30 − 1",
        digits=2,
        rule="per model: holds when the 95 % interval is above 0",
    )
    if need(c, [m for m in NN if m in have][:1], "extrapolate"):
        c.rows = [estimate(runs, [m], beyond_ratio("plain"), "positive") for m in NN if m in have]
        if nn and ca:
            c.rows.append(compare(runs, nn, ca, beyond_ratio("plain"), "greater"))
        _finish(c)
    c = Claim(
        "reinit-remedy",
        "§5.2",
        "re-initialising the states every MAX_TRANS lets the "
        "robot keep moving (proposed for the CA models)",
        "(d_end re-initialised − d_end plain) / d_30",
        digits=2,
        rule="per CA model: holds when the 95 % interval is above 0",
    )
    if need(c, [m for m in CA if m in have][:1], "extrapolate"):
        c.rows = [estimate(runs, [m], reinit_gain, "positive") for m in CA if m in have]
        _finish(c)
    c = Claim(
        "ca-initial-states",
        "§4",
        "CA motion becomes incoherent when the initial states "
        "change slightly; the NN model addresses this",
        "distance kept when k of the 30 initial states change by ±1 (% of d_30)",
        rule=GREATER + " (NN against CA, per k)",
    )
    if need(c, both, "initial-states"):
        ks = sorted(
            {
                int(k)
                for r in runs.get(have[0], ())
                for k in (lookup(r, "initial-states", "k") or {})
            }
        )
        for k in ks:
            row = compare(runs, nn, ca, kept(k), "greater")
            row.label = f"k = {k}: {row.label}"
            c.rows.append(row)
        _finish(c)
    c = Claim(
        "nnsig-clustering",
        "§5.2, Fig. 20",
        "NNsig's module states cluster: the next "
        "state is mostly the same or a neighbouring one; not so for NNsin",
        "fraction of non-lead module transitions with |S^(t+1) − S^t| ≤ 1 (%)",
        scale=100,
        rule=GREATER,
    )
    if need(c, NN):
        c.rows = [compare(runs, ["nnsig"], ["nnsin"], clustered, "greater")]
        _finish(c)
    return out


def _ranking(runs: Runs, have: Sequence[str], need: Need, walk: Metric, what: str) -> None:
    """The paper's claims on how far the models walk (§3.3, §3.4, §4.3), on ``walk``."""
    c = Claim(
        "ca2dsing-comparable-to-ca1d",
        "§3.3, Fig. 9",
        "CA2dSing's best fitness is comparable to CA1d's",
        what,
        scale=100,
        rule="holds when the 95 % interval of the difference of the means lies within "
        f"±{SIMILAR_FRACTION:.0%} of CA1d's mean; does not hold when p < 0.05",
    )
    if need(c, ("ca2dsing", "ca1d")):
        ca1d = stats.mean_interval(values(runs, ["ca1d"], walk)).mean or 0.0
        c.rows = [
            compare(runs, ["ca2dsing"], ["ca1d"], walk, "similar", SIMILAR_FRACTION * abs(ca1d))
        ]
        _finish(c)
    c = Claim(
        "ca2ddiff-best-ca",
        "§3.4, §6",
        "CA2dDiff reaches the highest fitness of the CA models",
        what,
        scale=100,
        rule=GREATER,
    )
    if need(c, CA):
        c.rows = [compare(runs, ["ca2ddiff"], [m], walk, "greater") for m in CA[:2]]
        _finish(c)
    c = Claim(
        "nnsin-furthest",
        "§4.3, §6",
        "NNsin covers the greatest distance (the highest fitness of all five models)",
        what,
        scale=100,
        rule=GREATER,
    )
    if need(c, ("nnsin",)):
        c.rows = [compare(runs, ["nnsin"], [m], walk, "greater") for m in have if m != "nnsin"]
        _finish(c)
    c = Claim(
        "nnsin-above-nnsig",
        "§4.3, Figs. 15, 16",
        "NNsin reaches a higher fitness than NNsig",
        what,
        scale=100,
        rule=GREATER,
    )
    if need(c, NN):
        c.rows = [compare(runs, ["nnsin"], ["nnsig"], walk, "greater")]
        _finish(c)


def _slowest(runs: Runs, have: Sequence[str], need: Need, walk: Metric, what: str) -> None:
    c = Claim("nnsig-slowest", "§5.2, Fig. 18", "NNsig is the slowest", what, scale=100,
              rule=SMALLER)  # fmt: skip
    if need(c, ("nnsig",)):
        c.rows = [compare(runs, ["nnsig"], [m], walk, "smaller") for m in have if m != "nnsig"]
        _finish(c)


#: what "on the uncertain robot" measures (issue 30 §3): the sensitivity analysis's joint sample
BOX_WHAT = "mean distance over the random robots of the run's uncertain box (cm)"
#: the same analysis's run on the nominal robot: the baseline the box verdicts are set beside
#: (a run's fitness is not that when it was scored otherwise, e.g. a --randomize run's
#: validation mean)
BOX_NOMINAL_WHAT = "distance on the nominal robot, the sensitivity analysis's first run (cm)"


def box_nominal(r: RunData) -> float | None:
    """``bstool sensitivity``'s run on the nominal robot (m)."""
    return lookup(r, "sensitivity", "nominal")


def evaluate_uncertain(
    runs: Runs, plan_models: Sequence[str], analyses: set[str], *, nominal: bool = False
) -> list[Claim]:
    """The paper's claims on how far the models walk, judged again on the uncertain robot:
    each run's mean distance over ``bstool sensitivity``'s random robots (the plan's
    ``[analyses] sensitivity``). ``nominal``: the same claims on that analysis's run on the
    nominal robot instead, the baseline measured the same way."""
    have = [m for m in plan_models if runs.get(m)]
    out: list[Claim] = []
    need = _checker(out, have, analyses, "sensitivity")
    walk, what = (box_nominal, BOX_NOMINAL_WHAT) if nominal else (box_mean, BOX_WHAT)
    _ranking(runs, have, need, walk, what)
    _slowest(runs, have, need, walk, what)
    return out
