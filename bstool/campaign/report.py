"""DIR/report of a campaign: index.html, report.json and the PNGs, made from DIR alone (its
plan.toml, the runs' best.json and history.csv, the cached analyses, campaign.json).

The analyses of finished runs that are not cached yet are computed first (the same cache the
campaign fills), so ``bstool report DIR`` and the end of ``bstool campaign`` write the same
report. Runs not finished yet are listed, not used.
"""

from __future__ import annotations

import datetime as dt
import math
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from bstool import fileio, outputs
from bstool.campaign import analyses as an
from bstool.campaign import claims as cl
from bstool.campaign import figures, pace, runner, stats
from bstool.campaign import plan as cp
from bstool.campaign import record as rec
from bstool.controllers import load_controller
from bstool.evolve.checkpoint import read_history
from bstool.experiments.report import is_report
from bstool.version import __version__

REPORT = "report"
FORMAT = "bstool.campaign-report/1"


def _run_data(run: runner.Run, results: dict[str, dict[str, Any]]) -> cl.RunData:
    c = load_controller(run.folder / "best.json")
    T = c.max_trans or 30
    return cl.RunData(
        name=run.name,
        model=run.spec.model,
        seed=run.spec.seed,
        fitness=c.fitness,
        history=read_history(run.folder / "history.csv"),
        results=results,
        states=c.states(T),
        transitions=T,
    )


def _untimed_note(generations: int) -> str:
    """What the campaign's wall time leaves out ("" when nothing)."""
    if not generations:
        return ""
    if generations == 1:
        what = "1 generation was made by a session killed before it saved its time"
    else:
        what = (
            f"{generations} generations were made by sessions killed before they saved their time"
        )
    return f"{what}, so it is a lower bound"


def _run_row(run: runner.Run, data: cl.RunData | None, record: rec.Record) -> dict[str, Any]:
    r = record.runs.get(run.name)
    if r is None:  # never seen by bstool campaign (bstool report on a folder it adopts later)
        r = rec.RunRecord(adopted_steps=run.steps_done)
    made = min(run.steps_done, run.total_steps)
    # generations in the folder that no saved session timed (a session killed before it
    # could save its record): the wall time shown is then a lower bound
    untimed = max(0, made - r.steps - r.adopted_steps)
    if r.adopted_steps and r.steps:
        wall = f"{pace.text(r.wall_s)} for {r.steps} generations; {r.adopted_steps} made before"
    elif r.adopted_steps:
        wall = f"not timed: its {r.adopted_steps} generations were made before the campaign"
    elif untimed and r.steps:
        wall = f"{pace.text(r.wall_s)} for {r.steps} of its {made} generations"
    else:
        wall = pace.text(r.wall_s) if r.steps else "—"
    if untimed and r.adopted_steps:
        wall += f" ({untimed} more not timed)"
    row: dict[str, Any] = {
        "name": run.name,
        "model": run.spec.model,
        "seed": run.spec.seed,
        "finished": run.done,
        "generations": f"{min(run.steps_done, run.total_steps)} of {run.total_steps}",
        "command": run.command,
        "wall": wall,
        "wall_s": r.wall_s,
        "adopted_steps": r.adopted_steps,
        "campaign_steps": r.steps,
        "untimed_steps": untimed,
        "metrics": None if data is None else _metrics(data),
    }
    return row


def _metrics(d: cl.RunData) -> dict[str, float | None]:
    out: dict[str, float | None] = {
        "fitness": d.fitness,
        "distance": cl.distance(d),
        "keep_80": cl.keep(80)(d),
        "keep_100": cl.keep(100)(d),
        "mean_md": cl.mean_mobility(d),
        "lead_md": cl.lead_mobility(d),
        "other_md": cl.other_mobility(d),
        "peak_at": cl.peak_at(d),
        "beyond": cl.beyond_ratio("plain")(d),
        "reinit": cl.reinit_gain(d),
        "max_dev": cl.max_deviation(d),
        "sway": cl.sway(d),
        "clustered": cl.clustered(d),
        "uncertain_kept": cl.uncertain_kept(d),
        "box_mean": cl.box_mean(d),
    }
    for k in sorted(cl.lookup(d, "initial-states", "k") or {}, key=int):
        out[f"kept_{k}"] = cl.kept(int(k))(d)
    return out


#: the per-model table's columns: key, heading, scale, digits
COLUMNS = (
    ("fitness", "fitness (cm)", 100, 1),
    ("distance", "d_30 (cm)", 100, 1),
    ("keep_80", "keep ≥ 80 %", 1, 1),
    ("keep_100", "keep 100 %", 1, 1),
    ("mean_md", "mean M_D (%)", 1, 1),
    ("lead_md", "lead M_D (%)", 1, 1),
    ("other_md", "other M_D (%)", 1, 1),
    ("peak_at", "peak at", 1, 0),
    ("beyond", "d_end / d_30 − 1", 1, 2),
    ("reinit", "re-init gain", 1, 2),
    ("max_dev", "max dev (cm)", 100, 1),
    ("sway", "sway (cm)", 100, 2),
    ("clustered", "ΔS within ±1 (%)", 100, 0),
    ("uncertain_kept", "kept on uncertain robots (%)", 100, 0),
    ("box_mean", "mean on uncertain robots (cm)", 100, 1),
)


def _model_rows(rows: Sequence[dict[str, Any]], models: Sequence[str]) -> list[dict[str, Any]]:
    out = []
    keys = [c[0] for c in COLUMNS] + sorted(
        {k for r in rows for k in (r["metrics"] or {}) if k.startswith("kept_")},
        key=lambda k: int(k.split("_")[1]),
    )
    for model in models:
        mine = [r["metrics"] for r in rows if r["model"] == model and r["metrics"]]
        cells = {}
        for key in keys:
            iv = stats.mean_interval([m.get(key) for m in mine])
            cells[key] = iv.to_json()
        out.append({"model": model, "runs": len(mine), "cells": cells})
    return out


def _columns(model_rows: Sequence[dict[str, Any]]) -> list[tuple[str, str, float, int]]:
    cols = [c for c in COLUMNS if any(r["cells"][c[0]]["mean"] is not None for r in model_rows)]
    kept = sorted(
        {k for r in model_rows for k in r["cells"] if k.startswith("kept_")},
        key=lambda k: int(k.split("_")[1]),
    )
    return cols + [(k, f"kept, k = {k.split('_')[1]} (%)", 1, 1) for k in kept]


def _fmt(cell: Mapping[str, Any], scale: float, digits: int) -> str:
    iv = stats.Interval(cell["mean"], cell["low"], cell["high"], cell["n"])
    return iv.text(scale, digits)


def build(
    folder: str | os.PathLike[str],
    plan: cp.CampaignPlan,
    settings: Mapping[str, cp.Setting],
    *,
    out: str | os.PathLike[str] | None = None,
    force: bool = False,
    workers: int | None = None,
    schedule_for: an.ScheduleFor | None = None,
    progress: an.Progress | None = None,
    analysed: Callable[[], None] | None = None,
) -> Path:
    """Analyse the finished runs (cached) and write the report; returns its index.html.
    ``analysed()`` is called between the two (the campaign saves its record there)."""
    base = Path(folder)
    target = outputs.check_dir(
        base / REPORT if out is None else out,
        "report folder",
        force=force,
        ours=is_report,
        protect=(base / runner.RUNS,),
    )
    runs = runner.check_runs(base, plan, settings)
    done = [r for r in runs if r.done]
    results = an.analyse(
        base,
        [(r.name, r.folder) for r in done],
        plan,
        workers=workers,
        schedule_for=schedule_for,
        progress=progress,
    )
    if progress is not None:
        progress.describe("report")
    if analysed is not None:
        analysed()
    data = {r.name: _run_data(r, results[r.name]) for r in done}
    by_model = {m: [data[r.name] for r in done if r.spec.model == m] for m in plan.models}
    names = {job.name for r in done for job in an.jobs(plan, data[r.name].transitions)}
    claims = cl.evaluate(by_model, plan.models, names)
    box = plan.analyses.sensitivity is not None
    uncertain = cl.evaluate_uncertain(by_model, plan.models, names) if box else []
    baseline = cl.evaluate_uncertain(by_model, plan.models, names, nominal=True) if box else []
    record = rec.load(base)
    run_rows = [_run_row(r, data.get(r.name), record) for r in runs]
    model_rows = _model_rows(run_rows, plan.models)
    kinds = {r.expected.fitness for r in runs}
    physics = kinds == {"physics"}
    plan_text = (base / cp.PLAN_FILE).read_text(encoding="utf-8")
    with outputs.staged_dir(target) as tmp:
        T = data[done[0].name].transitions if done else 30
        shown = _figures(tmp, by_model, plan, physics, T)
        context = {
            "title": "bstool campaign report: the paper's claims over the seeds",
            "version": __version__,
            "made": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "folder": str(base.resolve()),
            "adopted": sum(r["adopted_steps"] > 0 for r in run_rows),
            "untimed": _untimed_note(sum(r["untimed_steps"] for r in run_rows)),
            "plan": plan.to_json(),
            "plan_text": plan_text,
            "fitness_kind": ", ".join(sorted(kinds)),
            "physics": physics,
            "finished": len(done),
            "total": len(runs),
            "unfinished": [r.name for r in runs if not r.done],
            "runs": run_rows,
            "models": model_rows,
            "columns": _columns(model_rows),
            "claims": [c.to_json() for c in claims],
            "uncertain_claims": [c.to_json() for c in uncertain],
            "survival": survival(baseline, uncertain),
            "sensitivity": box,
            "figures": shown,
            "sessions": [vars(s) for s in record.sessions],
            "campaign_wall": pace.text(record.wall_s),
            "campaign_wall_s": record.wall_s,
            "rules": RULES,
            "confidence": stats.CONFIDENCE,
            "resamples": stats.RESAMPLES,
        }
        fileio.write_text(tmp / "index.html", _render(context))
        fileio.write_json(tmp / "report.json", {"format": FORMAT, **context})
        fileio.write_text(tmp / "tables.md", markdown(context))
    return target / "index.html"


def survival(baseline: Sequence[cl.Claim], uncertain: Sequence[cl.Claim]) -> list[dict[str, str]]:
    """Per claim judged on the uncertain robot: its verdict there beside its verdict on the
    nominal robot measured the same way (``evaluate_uncertain(..., nominal=True)``)."""
    nominal = {c.key: c for c in baseline}
    return [
        {
            "key": u.key,
            "nominal": nominal[u.key].shown if u.key in nominal else "—",
            "uncertain": u.shown,
        }
        for u in uncertain
    ]


def _md_row(cells: Sequence[Any]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _p(p: float | None) -> str:
    return "—" if p is None else (f"{p:.3f}" if p >= 0.001 else f"{p:.1e}")


def markdown(context: Mapping[str, Any]) -> str:
    """The report's tables in Markdown, for docs/results.md: the claims with their
    statistics, the models (mean [95 % interval] over the seeds) and the runs."""
    lines = [
        f"Campaign {context['folder']}: {context['finished']} of {context['total']} runs "
        f"finished; bstool {context['version']}, {context['made']}.",
        "",
        "## The paper's claims",
        "",
        *_md_claims(context["claims"]),
    ]
    lines += ["", "## The claims on the uncertain robot", ""]
    if not context.get("sensitivity"):
        lines.append("Not tested: the plan has no `[analyses] sensitivity`.")
    else:
        lines += [
            "Each run's mean distance over the random robots of its uncertain box (the plan's "
            "`[analyses] sensitivity`), beside the verdict on the same analysis's run on the "
            "nominal robot. All the other claims are judged on the nominal robot only.",
            "",
            _md_row(["claim", "nominal robot", "uncertain robot"]),
            "|---|---|---|",
            *(_md_row([u["key"], u["nominal"], u["uncertain"]]) for u in context["survival"]),
            "",
            *_md_claims(context["uncertain_claims"]),
        ]
    cols = context["columns"]
    lines += [
        "",
        "## Per model (mean [95 % interval] over the seeds)",
        "",
        _md_row(["model", "runs", *(c[1] for c in cols)]),
        "|" + "---|" * (len(cols) + 2),
    ]
    for m in context["models"]:
        cells = [_fmt(m["cells"][c[0]], c[2], c[3]) for c in cols]
        lines.append(_md_row([m["model"], m["runs"], *cells]))
    lines += [
        "",
        "## Per run",
        "",
        _md_row(["run", "generations", *(c[1] for c in cols), "wall time"]),
        "|" + "---|" * (len(cols) + 3),
    ]
    for r in context["runs"]:
        metrics = r.get("metrics") or {}
        cells = []
        for key, _, scale, digits in cols:
            v = metrics.get(key)
            cells.append("—" if v is None else f"{v * scale:.{digits}f}")
        lines.append(_md_row([r["name"], r["generations"], *cells, r["wall"]]))
    adopted = (
        (
            f", not counting the generations of {context['adopted']} run(s) made before the "
            "campaign adopted their folders"
        )
        if context["adopted"]
        else ""
    )
    untimed = f"; {context['untimed']}" if context["untimed"] else ""
    lines += ["", f"Campaign wall time: {context['campaign_wall']}{adopted}{untimed}.", ""]
    return "\n".join(lines)


def _md_claims(claims: Sequence[Mapping[str, Any]]) -> list[str]:
    """The claims with their statistics, one Markdown row per comparison."""
    lines = [
        _md_row(["claim", "paper", "comparison", "first", "second", "U", "p", "row", "verdict"]),
        "|" + "---|" * 9,
    ]
    for c in claims:
        rows = c["rows"] or [None]
        for i, r in enumerate(rows):
            head = [f"{c['key']} ({c['where']})", c["paper"]] if i == 0 else ["", ""]
            verdict = cl.shown_verdict(c)
            if r is None:
                lines.append(_md_row([*head, "—", "—", "—", "—", "—", "—", verdict]))
                continue
            t = r["test"]
            lines.append(
                _md_row(
                    [
                        *head,
                        r["label"],
                        _fmt(r["a"], c["scale"], c["digits"]),
                        "—" if r["b"] is None else _fmt(r["b"], c["scale"], c["digits"]),
                        "—" if t is None else f"{t['u']:.1f}",
                        _p(None if t is None else t["p"]),
                        r["verdict"],
                        f"**{verdict}**" if i == 0 else "",
                    ]
                )
            )
    return lines


RULES = (
    f"Each interval is the mean over the seeds with its {stats.CONFIDENCE:.0%} bootstrap "
    f"percentile interval ({stats.RESAMPLES} resamples, seed {stats.SEED}).",
    "A comparison of two models (or groups) is a two-sided Mann–Whitney U test of their runs: "
    f"the claim holds when p < {stats.ALPHA} in the paper's direction, does not hold when "
    f"p < {stats.ALPHA} the other way, and cannot be told apart otherwise.",
    "'Comparable' holds when the interval of the difference of the means lies within the "
    f"margin (±{cl.SIMILAR_FRACTION:.0%} of the reference's mean; ±{cl.SIMILAR_MD_POINTS:.0f} "
    "M_D points for CA1d's leads), does not hold when p < 0.05, cannot be told apart otherwise.",
    "A claim on one model holds when its whole interval is on the paper's side of 0, does not "
    "hold when it is wholly on the other side; a figure of the paper holds when it lies in the "
    "interval and does not hold when outside it.",
    "A claim of several rows holds when every row holds, does not hold when any row does not "
    "hold, and cannot be told apart otherwise. Fewer than 2 runs: cannot be told apart.",
)


FIGURES = (
    "fitness",
    "best_fitness",
    "faults",
    "leads",
    "multi",
    "paths",
    "extrapolation",
    "initial_states",
    "sensitivity",
    "gait_nnsin",
    "gait_nnsig",
    "state_changes",
)


def _figures(
    tmp: Path, runs: cl.Runs, plan: cp.CampaignPlan, physics: bool, transitions: int
) -> dict[str, str | None]:
    """Draw what the runs allow; the figure names the page shows."""
    shown: dict[str, str | None] = dict.fromkeys(FIGURES)
    if not any(runs.values()):
        return shown
    unit, scale = ("cm", 100.0) if physics else ("toy units", 1.0)
    figures.fitness_curves(tmp / "fitness.png", runs, unit, scale)
    figures.per_run_values(
        tmp / "best-fitness.png",
        runs,
        cl.fitness,
        f"best fitness ({unit})",
        "Best fitness of each run",
        scale,
    )
    shown.update({"fitness": "fitness.png", "best_fitness": "best-fitness.png"})
    a = plan.analyses
    if a.faults:
        figures.single_failures(tmp / "faults.png", runs)
        figures.leads(tmp / "leads.png", runs)
        shown.update({"faults": "faults.png", "leads": "leads.png"})
    if a.multi_failures:
        figures.multi_failures(tmp / "multi.png", runs)
        shown["multi"] = "multi.png"
    if a.paths:
        figures.paths(tmp / "paths.png", runs)
        shown["paths"] = "paths.png"
    if a.extrapolate is not None:
        figures.extrapolation(tmp / "extrapolation.png", runs, transitions)
        shown["extrapolation"] = "extrapolation.png"
    if a.sensitivity is not None:
        figures.per_run_values(
            tmp / "sensitivity.png",
            runs,
            cl.uncertain_kept,
            "joint sample's mean distance (% of nominal)",
            "Physics uncertainty: distance kept on random robots",
            100.0,
        )
        shown["sensitivity"] = "sensitivity.png"
    if a.initial_states is not None:
        figures.initial_states(tmp / "initial-states.png", runs)
        shown["initial_states"] = "initial-states.png"
    for model in ("nnsin", "nnsig"):
        mine = [r for r in runs.get(model, ()) if cl.distance(r) is not None]
        if mine:
            best = max(mine, key=lambda r: cl.distance(r) or -math.inf)
            figures.gait_map(tmp / f"gait-{model}.png", best)
            shown[f"gait_{model}"] = f"gait-{model}.png"
    if runs.get("nnsin") or runs.get("nnsig"):
        figures.state_changes(tmp / "state-changes.png", runs)
        shown["state_changes"] = "state-changes.png"
    return shown


def _render(context: dict[str, Any]) -> str:
    from bstool.experiments.report import template_env

    env = template_env()
    env.filters["cell"] = _fmt
    env.filters["interval"] = lambda iv, scale=1.0, digits=1: (
        "—" if iv is None else _fmt(iv, scale, digits)
    )
    env.filters["p"] = lambda p: "—" if p is None else (f"{p:.3f}" if p >= 0.001 else f"{p:.1e}")
    return env.get_template("campaign.html.j2").render(**context)
