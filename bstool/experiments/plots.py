"""Figures of the experiments: Fig. 17 (mobility per failed module), Fig. 19 (distance against
transition) and the multiple-failure curves. All written atomically as PNG (Agg backend)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bstool import fileio
from bstool.errors import InputError
from bstool.experiments.mobility import FaultRun, SingleFaults, summarize

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def new_figure(width: float, height: float) -> Figure:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure as _Figure

    return _Figure(figsize=(width, height), dpi=100)


def save_figure(fig: Figure, path: str | os.PathLike[str], fmt: str = "png") -> None:
    fig.tight_layout()
    try:
        with fileio.atomic_open(path, "wb") as fh:
            fig.savefig(fh, format=fmt)
    except OSError as exc:  # checked before the work; this is the disk filling up meanwhile
        raise InputError(f"cannot write the plot {path}: {exc.strerror or exc}") from None


def plot_single_failures(
    path: str | os.PathLike[str], results: Mapping[str, SingleFaults], title: str = ""
) -> None:
    """Grouped bars: M_D for each failed module L.M, one colour per controller (paper Fig. 17)."""
    first = next(iter(results.values()))
    labels = [str(r.failed[0]) for r in first.runs]
    x = np.arange(len(labels))
    fig = new_figure(max(8.0, 0.32 * len(labels) * max(1, len(results)) ** 0.5), 4.2)
    ax = fig.add_subplot()
    width = 0.8 / len(results)
    for idx, (name, res) in enumerate(results.items()):
        values = np.nan_to_num(np.array([r.mobility for r in res.runs]), nan=0.0)
        ax.bar(x + (idx - (len(results) - 1) / 2) * width, values, width, label=name)
    ax.axhline(100, color="0.3", linewidth=0.8)
    ax.axhline(80, color="0.6", linewidth=0.8, linestyle="--")
    ax.set_xticks(x, labels, rotation=90, fontsize=7)
    ax.set_xlabel("failed module (leg.module, 0 = lead)")
    ax.set_ylabel("degree of mobility M_D (%)")
    ax.set_title(title or "Degree of mobility under single module failure")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", linewidth=0.3)
    save_figure(fig, path)


def plot_multi_failures(
    path: str | os.PathLike[str], curves: Mapping[str, Mapping[int, Sequence[FaultRun]]]
) -> None:
    """Median M_D (with the interquartile band) against the number of failed modules."""
    fig = new_figure(6.0, 4.2)
    ax = fig.add_subplot()
    every_k: set[int] = set()
    for name, by_k in curves.items():
        ks = sorted(by_k)
        every_k.update(ks)
        stats = [summarize(by_k[k]) for k in ks]
        med = [s.get("median", np.nan) for s in stats]
        ax.plot(ks, med, marker="o", label=name)
        ax.fill_between(
            ks, [s.get("q1", np.nan) for s in stats], [s.get("q3", np.nan) for s in stats],
            alpha=0.2,
        )  # fmt: skip
    ax.axhline(100, color="0.3", linewidth=0.8)
    ax.axhline(80, color="0.6", linewidth=0.8, linestyle="--")
    ax.set_xticks(sorted(every_k))  # K is a count: integer ticks only
    ax.set_xlabel("failed modules K (random)")
    ax.set_ylabel("M_D (%): median and quartiles")
    ax.set_title("Mobility under multiple failures")
    ax.legend(fontsize=8)
    ax.grid(True, linewidth=0.3)
    save_figure(fig, path)


def plot_distance_curves(
    path: str | os.PathLike[str],
    curves: Mapping[str, np.ndarray],
    max_trans: int | None = None,
    title: str = "Distance against state transition",
) -> None:
    """Distance from the start after each transition (paper Fig. 19), in cm."""
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot()
    for name, curve in curves.items():
        ax.plot(np.arange(len(curve)), np.asarray(curve) * 100.0, label=name)
    if max_trans:
        ax.axvline(max_trans, color="0.5", linestyle="--", linewidth=0.8, label="MAX_TRANS")
    ax.set_xlabel("state transition")
    ax.set_ylabel("distance from start (cm)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, linewidth=0.3)
    save_figure(fig, path)


_POPULATION_LABEL = {"main": "", "control": " control rule", "leg": " leg rule"}


def plot_fitness(
    path: str | os.PathLike[str],
    histories: Mapping[str, Sequence[object]],
    title: str = "Fitness against generation",
) -> None:
    """Maximum (solid) and mean (dashed) fitness against generation, several runs overlaid
    (paper Figs 7, 9–11, 15–16). Rows are ``HistoryRow``s (generation, best, mean,
    population); co-evolution runs draw one pair of curves per population; a randomized run's
    validation means are drawn as open circles. The format comes
    from the file's suffix (.png, .svg, .pdf)."""
    fig = new_figure(8.0, 5.0)
    ax = fig.add_subplot()
    harm: Any = None  # parasites (--coevolve-faults) score a fraction of distance lost: own axis
    colours = [f"C{i}" for i in range(10)]
    curves = 0
    for name, rows in histories.items():
        for pop in dict.fromkeys(getattr(r, "population", "main") for r in rows):
            mine = [r for r in rows if getattr(r, "population", "main") == pop]
            colour = colours[curves % len(colours)]
            label = f"{name}{_POPULATION_LABEL.get(pop, ' ' + pop)}"
            gens = [getattr(r, "generation") for r in mine]  # noqa: B009
            scale, target = 100.0, ax
            if pop == "parasite":
                harm = harm or ax.twinx()
                scale, target = 1.0, harm
            best = [getattr(r, "best") * scale for r in mine]  # noqa: B009
            mean = [getattr(r, "mean") * scale for r in mine]  # noqa: B009
            target.plot(gens, best, color=colour, ls=":" if harm is target else "-",
                        label=f"{label} max")  # fmt: skip
            target.plot(gens, mean, color=colour, ls="-." if harm is target else "--",
                        label=f"{label} mean")  # fmt: skip
            checked = [(g, v * scale) for g, r in zip(gens, mine, strict=True)
                       if (v := getattr(r, "validation", None)) is not None]  # fmt: skip
            if checked:  # --randomize: the best's mean over the validation robots
                target.plot(*zip(*checked, strict=True), color=colour, ls="none", marker="o",
                            ms=5, mfc="white", label=f"{label} validation")  # fmt: skip
            curves += 1
    if harm is not None:
        harm.set_ylabel("parasites: fraction of distance lost")
        harm.legend(fontsize="small", loc="lower right")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness: distance after MAX_TRANS (cm)")
    ax.set_title(title)
    ax.grid(True, linewidth=0.3)
    ax.legend(fontsize="small")
    suffix = os.fspath(path).rsplit(".", 1)[-1].lower()
    save_figure(fig, path, suffix if suffix in ("svg", "pdf") else "png")
