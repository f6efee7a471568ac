"""The campaign report: the verdict rules, the claims on made-up runs, and a small campaign's
report from its folder alone, with the analyses cached by the digest of their inputs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bstool.campaign import claims as cl
from bstool.campaign import report as campaign_report
from bstool.campaign import stats

# -- the verdict rules ---------------------------------------------------------------------


def test_intervals() -> None:
    iv = stats.mean_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    assert iv.mean == 3.0 and iv.low is not None and iv.high is not None
    assert 1.0 <= iv.low < 3.0 < iv.high <= 5.0
    assert stats.mean_interval([1.0, 2.0, 3.0, 4.0, 5.0]) == iv  # seeded: the same every time
    assert stats.mean_interval([2.0, 2.0, 2.0]) == stats.Interval(2.0, 2.0, 2.0, 3)
    assert stats.mean_interval([2.0, None, float("nan")]) == stats.Interval(2.0, None, None, 1)
    assert stats.mean_interval([]) == stats.Interval(None, None, None, 0)
    d = stats.difference_interval([10.0, 11, 12, 13, 14], [1.0, 2, 3, 4, 5])
    assert d.mean == 9.0 and d.low is not None and d.low > 0


def test_the_rules() -> None:
    low, high = [1.0, 2, 3, 4, 5], [6.0, 7, 8, 9, 10]
    t = stats.mann_whitney(high, low)
    assert t is not None and t.p == pytest.approx(2 / 252) and t.direction == 1
    assert stats.greater(t) == stats.HOLDS and stats.smaller(t) == stats.FAILS
    back = stats.mann_whitney(low, high)
    assert stats.greater(back) == stats.FAILS and stats.smaller(back) == stats.HOLDS
    mixed = stats.mann_whitney([1.0, 5, 3, 8, 2], [2.5, 4, 6, 1.5, 7])
    assert stats.greater(mixed) == stats.UNCLEAR
    assert stats.greater(None) == stats.UNCLEAR
    same = [10.0, 10.1, 9.9, 10.05, 9.95]
    close = stats.difference_interval(same, [x + 0.01 for x in same])
    near = stats.mann_whitney(same, [x + 0.01 for x in same])
    assert stats.similar(near, close, 1.0) == stats.HOLDS
    assert stats.similar(near, close, 0.001) == stats.UNCLEAR
    assert stats.similar(t, stats.difference_interval(high, low), 100.0) == stats.FAILS
    assert stats.positive(stats.mean_interval([1.0, 2, 3])) == stats.HOLDS
    assert stats.negative(stats.mean_interval([1.0, 2, 3])) == stats.FAILS
    assert stats.positive(stats.mean_interval([-1.0, 2, 3])) == stats.UNCLEAR
    assert stats.matches(stats.mean_interval([14.0, 15, 16, 17]), 15) == stats.HOLDS
    assert stats.matches(stats.mean_interval([14.0, 15, 16, 17]), 8) == stats.FAILS
    assert stats.combined([stats.HOLDS, stats.HOLDS]) == stats.HOLDS
    assert stats.combined([stats.HOLDS, stats.UNCLEAR]) == stats.UNCLEAR
    assert stats.combined([stats.UNCLEAR, stats.FAILS]) == stats.FAILS


def _runs(fitness: dict[str, list[float]]) -> dict[str, list[cl.RunData]]:
    states = np.zeros((3, 5, 6), dtype=np.int64)
    return {
        m: [cl.RunData(f"{m}-s{i}", m, i, f, [], {}, states, 2) for i, f in enumerate(values)]
        for m, values in fitness.items()
    }


def _claim(claims: list[cl.Claim], key: str) -> cl.Claim:
    return next(c for c in claims if c.key == key)


BASE = [0.30, 0.31, 0.32, 0.33, 0.34]


def _paper_order() -> dict[str, list[cl.RunData]]:
    """Five seeds a model, ordered as the paper says: nnsin furthest, ca2ddiff the best CA,
    ca2dsing as far as ca1d."""
    return _runs({
        "nnsin": [x + 0.2 for x in BASE], "nnsig": BASE, "ca1d": BASE,
        "ca2dsing": [x + 0.001 for x in BASE], "ca2ddiff": [x + 0.1 for x in BASE],
    })  # fmt: skip


def test_claims_on_made_up_runs() -> None:
    runs = _paper_order()
    claims = cl.evaluate(runs, list(runs), set())
    assert [c.key for c in claims] == [
        "fitness-rises",
        "ca2dsing-comparable-to-ca1d",
        "ca2ddiff-best-ca",
        "nnsin-furthest",
        "nnsin-above-nnsig",
        "nn-tolerate-failures",
        "fig17-counts",
        "lead-failures-hurt-most",
        "ca2ddiff-most-resilient",
        "nnsig-slowest",
        "nnsig-straightest",
        "nnsig-smoothest",
        "ca-stall-beyond-max-trans",
        "nn-progress-beyond-max-trans",
        "reinit-remedy",
        "ca-initial-states",
        "nnsig-clustering",
    ]  # fmt: skip (the paper's order)
    assert _claim(claims, "nnsin-furthest").verdict == stats.HOLDS
    assert _claim(claims, "nnsin-above-nnsig").verdict == stats.HOLDS
    assert _claim(claims, "ca2ddiff-best-ca").verdict == stats.HOLDS
    assert _claim(claims, "ca2dsing-comparable-to-ca1d").verdict == stats.HOLDS
    faults = _claim(claims, "nn-tolerate-failures")
    assert faults.verdict == cl.NOT_TESTED and "[analyses] faults" in (faults.missing or "")
    runs["nnsin"] = runs["nnsin"][:1]  # one seed: nothing can be told
    claims = cl.evaluate(runs, list(runs), set())
    assert _claim(claims, "nnsin-furthest").verdict == stats.UNCLEAR
    runs = _runs({"nnsin": BASE, "nnsig": [x + 0.2 for x in BASE]})
    claims = cl.evaluate(runs, list(runs), set())
    assert _claim(claims, "nnsin-above-nnsig").verdict == stats.FAILS
    assert (
        _claim(claims, "ca2ddiff-best-ca").missing == "no finished run of ca1d, ca2dsing, ca2ddiff"
    )


def _box(runs: dict[str, list[cl.RunData]], means: dict[str, list[float]]) -> None:
    """Each run's sensitivity analysis: its box mean; its nominal run equal to its fitness."""
    for model, rs in runs.items():
        for r, mean in zip(rs, means[model], strict=True):
            r.results["sensitivity"] = {"mean": mean, "nominal": r.fitness, "kept": 0.5}


def test_a_claim_not_tested_shows_why_in_every_table() -> None:
    claim = cl.Claim("nn_vs_ca", "§3", "NN tolerate failures", "cm")
    assert claim.shown == stats.UNCLEAR == cl.shown_verdict(claim.to_json())
    claim.missing, claim.verdict = "no finished nnsig run", cl.NOT_TESTED
    assert claim.shown == "not tested: no finished nnsig run" == cl.shown_verdict(claim.to_json())
    row = campaign_report.survival([claim], [claim])[0]
    assert row["nominal"] == row["uncertain"] == claim.shown


def test_the_claims_on_the_uncertain_robot_read_the_box_mean() -> None:
    runs = _paper_order()  # on the box below, the order turns around
    _box(runs, {m: [base + 0.001 * i for i in range(5)] for m, base in
                {"nnsin": 0.05, "nnsig": 0.02, "ca1d": 0.25, "ca2dsing": 0.2505,
                 "ca2ddiff": 0.10}.items()})  # fmt: skip
    every = {"faults", "extrapolate", "initial-states", "sensitivity"}
    nominal = cl.evaluate(runs, list(runs), every)
    uncertain = cl.evaluate_uncertain(runs, list(runs), every)
    baseline = cl.evaluate_uncertain(runs, list(runs), every, nominal=True)
    keys = ["ca2dsing-comparable-to-ca1d", "ca2ddiff-best-ca", "nnsin-furthest",
            "nnsin-above-nnsig", "nnsig-slowest"]  # fmt: skip
    assert [c.key for c in uncertain] == [c.key for c in baseline] == keys
    assert all(c.metric == cl.BOX_WHAT for c in uncertain)
    assert all(c.metric == cl.BOX_NOMINAL_WHAT for c in baseline)
    for key in keys[:4]:  # the baseline is the nominal verdict where fitness is the distance
        assert _claim(baseline, key).verdict == _claim(nominal, key).verdict
    assert _claim(baseline, "nnsig-slowest").verdict == stats.UNCLEAR  # as far as ca1d
    assert _claim(uncertain, "nnsin-furthest").verdict == stats.FAILS  # ca1d walks further
    assert _claim(uncertain, "ca2ddiff-best-ca").verdict == stats.FAILS
    assert _claim(uncertain, "nnsin-above-nnsig").verdict == stats.HOLDS
    assert _claim(uncertain, "nnsig-slowest").verdict == stats.HOLDS
    assert _claim(uncertain, "ca2dsing-comparable-to-ca1d").verdict == stats.HOLDS
    row = _claim(uncertain, "nnsin-furthest").rows[0]
    assert row.a.mean == pytest.approx(0.052)  # the box means, not the fitness
    table = {u["key"]: u for u in campaign_report.survival(baseline, uncertain)}
    assert table["nnsin-furthest"] == {
        "key": "nnsin-furthest", "nominal": stats.HOLDS, "uncertain": stats.FAILS,
    }  # fmt: skip
    lacking = cl.evaluate_uncertain(runs, list(runs), every - {"sensitivity"})
    assert {c.verdict for c in lacking} == {cl.NOT_TESTED}
    assert lacking[0].missing == "the plan has no [analyses] sensitivity"


def test_comparable_on_the_box_takes_its_margin_from_the_box_mean() -> None:
    """CA2dSing against CA1d: the margin is 10 % of CA1d's box mean (0.54 cm here), not of
    its fitness (3.2 cm), so a 0.3 cm difference of box means is not shown comparable."""
    runs = _paper_order()
    means = {m: [0.05] * 5 for m in runs}
    means["ca1d"] = [0.050, 0.052, 0.054, 0.056, 0.058]
    means["ca2dsing"] = [0.049, 0.053, 0.057, 0.061, 0.065]  # interleaved: p is large
    _box(runs, means)
    claim = _claim(cl.evaluate_uncertain(runs, list(runs), {"sensitivity"}),
                   "ca2dsing-comparable-to-ca1d")  # fmt: skip
    assert claim.rows[0].test is not None and claim.rows[0].test.p > 0.05
    assert claim.verdict == stats.UNCLEAR


# -- a small campaign's report -------------------------------------------------------------

PLAN = """format = "bstool.campaign/1"
models = ["nnsig", "ca1d"]
seeds = [1, 2]

[evolve]
pop = 4
gens = 2
fitness = "toy"
transitions = 2

[analyses]
faults = true
multi-failures = 1
extrapolate = { transitions = 4 }
paths = true
initial-states = { k = [1, 3], samples = 2 }
sensitivity = { points = 2, samples = 2 }
"""


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from bstool.cli import main

    d = tmp_path_factory.mktemp("report")
    (d / "plan.toml").write_text(PLAN)
    assert main(["campaign", str(d / "plan.toml"), "-o", str(d / "C"), "-q"]) == 0
    return d / "C"


def _mtimes(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns
            for p in sorted((folder / "analyses").rglob("*.json"))}  # fmt: skip


def _stable(report: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in report.items() if k not in ("made", "sessions", "campaign_wall",
                                                         "campaign_wall_s", "runs")}  # fmt: skip


@pytest.mark.slow
def test_the_report(folder: Path, cli: Any) -> None:
    report = json.loads((folder / "report" / "report.json").read_text())
    assert report["format"] == "bstool.campaign-report/1"
    assert report["finished"] == report["total"] == 4
    keys = {c["key"] for c in report["claims"]}
    assert {"fitness-rises", "nnsin-above-nnsig", "fig17-counts", "lead-failures-hurt-most",
            "nnsig-straightest", "ca-initial-states", "nnsig-clustering"} <= keys  # fmt: skip
    verdicts = {stats.HOLDS, stats.FAILS, stats.UNCLEAR, cl.NOT_TESTED}
    assert {c["verdict"] for c in report["claims"]} <= verdicts
    for c in report["claims"]:
        for row in c["rows"]:
            if row["test"] is not None:
                assert 0 <= row["test"]["p"] <= 1
    assert [u["key"] for u in report["survival"]] == [c["key"] for c in report["uncertain_claims"]]
    assert "nnsin-above-nnsig" in {c["key"] for c in report["uncertain_claims"]}
    assert "## The claims on the uncertain robot" in (folder / "report" / "tables.md").read_text()
    page = (folder / "report" / "index.html").read_text()
    assert "<h2>The claims on the uncertain robot</h2>" in page
    assert page.count("<b>nnsin-above-nnsig</b>") == 2  # both claim tables, by the one macro
    figures = {n for n in report["figures"].values() if n}
    assert {"fitness.png", "faults.png", "paths.png", "extrapolation.png", "initial-states.png",
            "gait-nnsig.png", "state-changes.png", "sensitivity.png"} <= figures  # fmt: skip
    assert all((folder / "report" / n).is_file() for n in figures)
    html = (folder / "report" / "index.html").read_text()
    assert "bstool evolve nnsig --pop 4 --gens 2 --fitness toy --transitions 2 --seed 1" in html
    assert "format = &#34;bstool.campaign/1&#34;" in html  # the plan, verbatim
    # bstool report DIR: the same page from DIR alone, nothing computed again
    before = _mtimes(folder)
    again = cli("report", str(folder), "-q")
    assert again.code == 0, again.err
    assert _mtimes(folder) == before
    assert _stable(json.loads((folder / "report" / "report.json").read_text())) == _stable(report)
    # a changed best.json: its analyses are computed again, the others' are kept
    best = folder / "runs" / "ca1d-s2" / "best.json"
    obj = json.loads(best.read_text())
    obj["fitness"] = 0.5
    best.write_text(json.dumps(obj))
    assert cli("report", str(folder), "-o", str(folder.parent / "elsewhere"), "-q").code == 0
    after = _mtimes(folder)
    changed = {k for k in after if after[k] != before[k]}
    assert changed == {k for k in after if k.startswith("analyses/ca1d-s2/")}
    assert (folder.parent / "elsewhere" / "index.html").is_file()


@pytest.mark.slow
def test_a_stamp_timed_runs_analyses_use_the_schedule_model_it_was_scored_on() -> None:
    """--schedule-builds K: the analyses play the run on the ensemble of K builds it was scored
    on (not the one averaged model), and the cache digest says so."""
    import dataclasses

    from conftest import traced_controller

    from bstool.campaign.analyses import evaluation
    from bstool.commands.campaign import analysis_schedule
    from bstool.controllers import load_controller

    c = load_controller(traced_controller("nnsig"))
    ensemble = dataclasses.replace(c, ga={**(c.ga or {}), "schedule_builds": 2})
    assert evaluation(c) == {"kind": "stamp-timed", "period": None}  # digests kept
    assert evaluation(ensemble)["builds"] == 2
    assert len(analysis_schedule(ensemble, None).variants) == 2
    assert not getattr(analysis_schedule(c, None), "variants", ())
