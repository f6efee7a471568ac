"""The campaign report's figures: the paper's Figs. 7/9/15/16 (fitness per generation, one
panel per model, the mean over seeds with the range as a band), 17 (M_D per failed module),
18 (paths), 19 (distance beyond MAX_TRANS), §4 (changed initial states) and 20 (module states
over time; state changes). PNG, Agg backend, written atomically."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bstool.campaign.analyses import MULTI_K
from bstool.campaign.claims import RunData, lead_mobility, lookup, other_mobility
from bstool.experiments import gait
from bstool.experiments.plots import new_figure, save_figure

Runs = Mapping[str, Sequence[RunData]]


def _grid(count: int, width: float = 4.2, height: float = 3.2) -> tuple[Any, list[Any]]:
    cols = min(3, max(1, count))
    rows = math.ceil(count / cols)
    fig = new_figure(width * cols, height * rows)
    axes = [fig.add_subplot(rows, cols, i + 1) for i in range(count)]
    return fig, axes


def _band(
    ax: Any,
    x: np.ndarray,
    curves: list[np.ndarray],
    colour: str,
    label: str,
    style: str = "-",
    scale: float = 1.0,
) -> None:
    """The mean of ``curves`` (cut to the shortest) with the min–max range as a band."""
    if not curves:
        return
    n = min(len(c) for c in curves)
    stack = np.vstack([np.asarray(c[:n], dtype=float) for c in curves]) * scale
    ax.plot(x[:n], np.nanmean(stack, axis=0), style, color=colour, label=label)
    if len(curves) > 1:
        ax.fill_between(
            x[:n],
            np.nanmin(stack, axis=0),
            np.nanmax(stack, axis=0),
            color=colour,
            alpha=0.18,
            linewidth=0,
        )


def fitness_curves(path: Path, runs: Runs, unit: str, scale: float) -> None:
    """Best and mean fitness per generation: the mean over seeds, the range as a band.
    ca2ddiff's steps (leg and control populations in turn, §3.4) are counted in order."""
    models = [m for m in runs if runs[m]]
    fig, axes = _grid(len(models))
    for ax, model in zip(axes, models, strict=True):
        best, mean = [], []
        for r in runs[model]:
            rows = [h for h in r.history if h.population != "parasite"]
            best.append(np.array([h.best for h in rows]))
            mean.append(np.array([h.mean for h in rows]))
        x = np.arange(max((len(b) for b in best), default=0))
        _band(ax, x, best, "C0", "best", scale=scale)
        _band(ax, x, mean, "C1", "population mean", "--", scale=scale)
        ax.set_title(f"{model} ({len(runs[model])} seeds)")
        ax.set_xlabel("generation" + (" (leg and control steps)" if model == "ca2ddiff" else ""))
        ax.set_ylabel(f"fitness ({unit})")
        ax.grid(True, linewidth=0.3)
        ax.legend(fontsize=7)
    save_figure(fig, path)


def per_run_values(
    path: Path, runs: Runs, metric: Any, ylabel: str, title: str, scale: float = 1.0
) -> None:
    """One dot per run, the models side by side, with each model's mean as a bar."""
    fig = new_figure(6.5, 4.0)
    ax = fig.add_subplot()
    models = [m for m in runs if runs[m]]
    for i, model in enumerate(models):
        vals = [metric(r) for r in runs[model]]
        vals = [v * scale for v in vals if v is not None and math.isfinite(v)]
        if not vals:
            continue
        jitter = np.linspace(-0.12, 0.12, len(vals)) if len(vals) > 1 else np.zeros(1)
        ax.plot(i + jitter, vals, "o", color=f"C{i}", alpha=0.8)
        ax.hlines(np.mean(vals), i - 0.3, i + 0.3, color=f"C{i}", linewidth=2)
    ax.set_xticks(range(len(models)), models)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, axis="y", linewidth=0.3)
    save_figure(fig, path)


def single_failures(path: Path, runs: Runs) -> None:
    """Fig. 17: M_D for each failed module L.M, the mean over seeds with the range."""
    models = [m for m in runs if any(lookup(r, "faults") for r in runs[m])]
    fig, axes = _grid(len(models), 5.5, 3.2)
    for ax, model in zip(axes, models, strict=True):
        tables = [
            np.array(
                [
                    [np.nan if x is None else x for x in row]
                    for row in lookup(r, "faults", "mobility")
                ],
                dtype=float,
            )
            for r in runs[model]
            if lookup(r, "faults")
        ]
        stack = np.stack([t.ravel() for t in tables])
        legs, modules = tables[0].shape
        x = np.arange(stack.shape[1])
        mean = np.nanmean(stack, axis=0)
        err = np.vstack([mean - np.nanmin(stack, axis=0), np.nanmax(stack, axis=0) - mean])
        colours = ["C3" if i % modules == 0 else "C0" for i in x]
        ax.bar(x, mean, color=colours, yerr=err, error_kw={"linewidth": 0.6})
        ax.axhline(100, color="0.3", linewidth=0.8)
        ax.axhline(80, color="0.6", linewidth=0.8, linestyle="--")
        ax.set_xticks(x[::modules], [f"L{i}" for i in range(legs)])
        ax.set_title(f"{model}: M_D per failed module (leads red)", fontsize=9)
        ax.set_ylabel("M_D (%)")
        ax.grid(True, axis="y", linewidth=0.3)
    save_figure(fig, path)


def leads(path: Path, runs: Runs) -> None:
    """Mean M_D of the lead failures against the other modules', one dot per run."""
    fig = new_figure(6.5, 4.0)
    ax = fig.add_subplot()
    models = [m for m in runs if any(lookup(r, "faults") for r in runs[m])]
    for i, model in enumerate(models):
        for dx, metric, colour in ((-0.15, lead_mobility, "C3"), (0.15, other_mobility, "C0")):
            vals = [v for v in (metric(r) for r in runs[model]) if v is not None]
            ax.plot(np.full(len(vals), i + dx), vals, "o", color=colour, alpha=0.7)
            if vals:
                ax.hlines(np.mean(vals), i + dx - 0.1, i + dx + 0.1, color=colour, linewidth=2)
    ax.plot([], [], "o", color="C3", label="lead failed")
    ax.plot([], [], "o", color="C0", label="another module failed")
    ax.set_xticks(range(len(models)), models)
    ax.set_ylabel("mean M_D (%)")
    ax.set_title("Failed leads against the other modules")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", linewidth=0.3)
    save_figure(fig, path)


def multi_failures(path: Path, runs: Runs) -> None:
    """Median M_D against K failed modules: the mean over seeds, the range as a band."""
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot()
    for i, model in enumerate(runs):
        curves, ks = [], None
        for r in runs[model]:
            by_k = lookup(r, "multi-failures", "k")
            if not by_k:
                continue
            ks = sorted(by_k, key=int)
            curves.append(np.array([by_k[k]["summary"].get("median", np.nan) for k in ks]))
        if ks:
            _band(ax, np.array([int(k) for k in ks]), curves, f"C{i}", model)
    ax.axhline(100, color="0.3", linewidth=0.8)
    ax.axhline(80, color="0.6", linewidth=0.8, linestyle="--")
    ax.set_xticks(list(MULTI_K))
    ax.set_xlabel("failed modules K (random sets)")
    ax.set_ylabel("median M_D (%)")
    ax.set_title("Mobility under multiple failures (mean over seeds, range)")
    ax.legend(fontsize=8)
    ax.grid(True, linewidth=0.3)
    save_figure(fig, path)


def paths(path: Path, runs: Runs) -> None:
    """Fig. 18: every run's disc path over MAX_TRANS, one panel per model, the best bold."""
    models = [m for m in runs if runs[m]]
    fig, axes = _grid(len(models), 4.0, 4.0)
    for ax, model in zip(axes, models, strict=True):
        done = [r for r in runs[model] if lookup(r, "base")]
        best = max(done, key=lambda r: lookup(r, "base", "distance"), default=None)
        for r in done:
            xy = np.asarray(lookup(r, "base", "path"), dtype=float)
            xy = (xy - xy[0]) * 100
            bold = r is best
            ax.plot(
                xy[:, 0],
                xy[:, 1],
                linewidth=1.8 if bold else 0.8,
                alpha=1 if bold else 0.5,
                label=f"{r.name} ({lookup(r, 'base', 'distance') * 100:.1f} cm)",
            )
        ax.plot([0], [0], "ks", markersize=4)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(model)
        ax.set_xlabel("x (cm)")
        ax.set_ylabel("y (cm)")
        ax.grid(True, linewidth=0.3)
        ax.legend(fontsize=6)
    save_figure(fig, path)


def extrapolation(path: Path, runs: Runs, transitions: int) -> None:
    """Fig. 19: distance from the start against transition, plain and re-initialised every
    MAX_TRANS (the mean over seeds, the range as a band)."""
    fig = new_figure(11.0, 4.2)
    for panel, which, title in ((1, "plain", "plain"), (2, "reinit", "re-initialised")):
        ax = fig.add_subplot(1, 2, panel)
        for i, model in enumerate(runs):
            curves = [
                np.asarray(lookup(r, "extrapolate", which), dtype=float)
                for r in runs[model]
                if lookup(r, "extrapolate")
            ]
            if curves:
                _band(ax, np.arange(len(curves[0])), curves, f"C{i}", model, scale=100)
        ax.axvline(transitions, color="0.5", linestyle="--", linewidth=0.8)
        ax.set_xlabel("state transition")
        ax.set_ylabel("distance from the start (cm)")
        ax.set_title(f"Distance against transition, {title}")
        ax.grid(True, linewidth=0.3)
        ax.legend(fontsize=8)
    save_figure(fig, path)


def initial_states(path: Path, runs: Runs) -> None:
    """§4: distance kept when k initial states change by ±1 (mean over seeds, range)."""
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot()
    shown_k: set[int] = set()
    for i, model in enumerate(runs):
        curves, ks = [], None
        for r in runs[model]:
            by_k = lookup(r, "initial-states", "k")
            if not by_k:
                continue
            ks = sorted(by_k, key=int)
            curves.append(
                np.array(
                    [np.nan if by_k[k]["mean_kept"] is None else by_k[k]["mean_kept"] for k in ks]
                )
            )
        if ks:
            shown_k.update(int(k) for k in ks)
            _band(ax, np.array([int(k) for k in ks]), curves, f"C{i}", model, "-o")
    ax.axhline(100, color="0.3", linewidth=0.8)
    if shown_k:
        ax.set_xticks(sorted(shown_k))  # k is a count: integer ticks only
    ax.set_xlabel("initial states changed by ±1 (k of 30)")
    ax.set_ylabel("distance kept (% of d_30)")
    ax.set_title("Sensitivity to the initial states (§4)")
    ax.legend(fontsize=8)
    ax.grid(True, linewidth=0.3)
    save_figure(fig, path)


def gait_map(path: Path, run: RunData) -> None:
    """Fig. 20: each module's state over time (rows L.M, lead first), as a heat map."""
    seq = np.asarray(run.states)
    T, n, m = seq.shape
    fig = new_figure(max(6.0, 0.16 * T + 2), 0.16 * n * m + 1.6)
    ax = fig.add_subplot()
    image = ax.imshow(
        seq.reshape(T, n * m).T,
        aspect="auto",
        cmap="viridis",
        interpolation="nearest",
        vmin=0,
        vmax=15,
    )
    ax.set_yticks(range(0, n * m), [f"{i}.{j}" for i in range(n) for j in range(m)], fontsize=6)
    ax.set_xticks(range(0, T, max(1, T // 15)))
    ax.set_xlabel("transition t")
    ax.set_ylabel("module L.M")
    d = lookup(run, "base", "distance")
    reached = "" if d is None else f" (d_{run.transitions} = {d * 100:.1f} cm)"
    ax.set_title(f"{run.name}: module states S^t{reached}")
    fig.colorbar(image, ax=ax, label="state")
    save_figure(fig, path)


def state_changes(path: Path, runs: Runs, models: Sequence[str] = ("nnsig", "nnsin")) -> None:
    """How far a non-lead module's state moves per transition, over every run of each model
    (fraction of module transitions)."""
    fig = new_figure(6.5, 4.0)
    ax = fig.add_subplot()
    shown = [m for m in models if runs.get(m)]
    width = 0.8 / max(1, len(shown))
    for i, model in enumerate(shown):
        k = 16
        counts = np.sum([gait.change_histogram(r.states, k) for r in runs[model]], axis=0)
        frac = counts / max(1, counts.sum())
        ax.bar(np.arange(k) + (i - (len(shown) - 1) / 2) * width, frac, width, label=model)
    ax.set_xlabel("|S^(t+1) − S^t| (non-lead modules)")
    ax.set_ylabel("fraction of module transitions")
    ax.set_title("State changes per transition (Fig. 20, §5.2)")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", linewidth=0.3)
    save_figure(fig, path)
