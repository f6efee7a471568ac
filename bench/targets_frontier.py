"""Issue 29 §5's three targets for every gait of a model at once: where its gaits lie.

Reads the summary.json of ``bench/reship_randomized.py --measure-only --also NAME=C.json ...``
(every gait measured on the same fresh robots of the default box, with the gait shipped before
as ``shipped``) and prints, per gait, the three ratios the issue sets against the gait shipped
before: the box mean (target >= 1.3x), the 10th percentile as a fraction of the gait's own
nominal distance (>= 50 %) and the nominal distance (>= 0.85x), and how many it meets. With
``--plot P.png``: the nominal ratio against the p10 fraction per model, the target region
shaded, each gait's marker filled when it also meets the mean target: the trade-off between
the nominal distance and the tail as a picture.

Usage: python bench/targets_frontier.py SUMMARY.json [--plot P.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from bstool import fileio

MEAN_TARGET = 1.3
P10_TARGET = 0.5
NOMINAL_TARGET = 0.85


def ratios(figures: dict[str, Any], base: dict[str, Any]) -> dict[str, float]:
    """One gait's three ratios against the gait shipped before (``base``); a figure divided
    by a zero one counts as 0 (a gait that does not move meets no target)."""

    def over(a: float, b: float) -> float:
        return a / b if b > 0 else 0.0

    return {
        "mean": over(figures["mean"], base["mean"]),
        "p10": over(figures["p10"], figures["nominal"]),
        "nominal": over(figures["nominal"], base["nominal"]),
    }


def met(r: dict[str, float]) -> list[bool]:
    """Which of the three targets (mean, p10, nominal) ``r`` meets."""
    return [r["mean"] >= MEAN_TARGET, r["p10"] >= P10_TARGET, r["nominal"] >= NOMINAL_TARGET]


def _figures_key(f: dict[str, Any]) -> tuple[float, float, float]:
    return (f["nominal"], f["mean"], f["p10"])


def table(summary: dict[str, Any]) -> tuple[dict[str, dict[str, dict[str, float]]], list[str]]:
    """Per model, per gait (the baseline left out), its ratios; and one line per gait left out
    because it is another's copy (the same figures on the same robots: e.g. the shipped file,
    also measured under the name of the run it came from), so that no gait counts twice."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    copies: list[str] = []
    for model, entry in summary.items():
        runs = entry["runs"]
        base = runs.get("shipped")
        if base is None:
            raise SystemExit(f"{model}: no 'shipped' gait in the summary to compare with")
        seen: dict[tuple[float, float, float], str] = {}
        out[model] = {}
        for name, f in runs.items():
            if name == "shipped":
                continue
            key = _figures_key(f)
            if key in seen:
                copies.append(f"{model}: {name} is {seen[key]} (the same figures), counted once")
                continue
            seen[key] = name
            out[model][name] = ratios(f, base)
        if not out[model]:
            raise SystemExit(f"{model}: no gait besides 'shipped' in the summary")
    return out, copies


def _group(name: str) -> str:
    """The legend group of a gait: its campaign (the part of its name before ':')."""
    return name.partition(":")[0] if ":" in name else name


def plot(rows: dict[str, dict[str, dict[str, float]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    groups = sorted({_group(n) for gaits in rows.values() for n in gaits})
    colours = {g: plt.get_cmap("tab10")(i % 10) for i, g in enumerate(groups)}
    fig, axes = plt.subplots(1, len(rows), figsize=(5.5 * len(rows), 4.6), squeeze=False)
    for ax, (model, gaits) in zip(axes[0], rows.items(), strict=True):
        right = max(1.4, max(r["nominal"] for r in gaits.values()) + 0.05)
        top = max(1.0, max(r["p10"] for r in gaits.values()) + 0.05)
        ax.fill_between([NOMINAL_TARGET, right], P10_TARGET, top, color="tab:green", alpha=0.15)
        for name, r in gaits.items():
            colour = colours[_group(name)]
            ax.scatter(
                r["nominal"],
                r["p10"],
                s=45,
                edgecolors=[colour],
                facecolors=[colour] if r["mean"] >= MEAN_TARGET else "none",
            )
        # the legend from proxies: a group's first marker may be filled or not
        mine = sorted({_group(n) for n in gaits})
        handles = [
            Line2D(
                [],
                [],
                marker="o",
                linestyle="",
                markerfacecolor="none",
                markeredgecolor=colours[g],
                label=g,
            )
            for g in mine
        ]
        handles.append(
            Line2D(
                [],
                [],
                marker="o",
                linestyle="",
                color="grey",
                label=f"filled: box mean >= {MEAN_TARGET}x too",
            )
        )
        handles.append(
            Line2D(
                [],
                [],
                marker="s",
                linestyle="",
                color="tab:green",
                alpha=0.3,
                label="nominal and p10 targets",
            )
        )
        ax.set_xlabel("nominal distance / the gait shipped before")
        ax.set_ylabel("10th percentile / own nominal")
        ax.set_title(model)
        ax.set_ylim(0, top)
        ax.legend(handles=handles, loc="upper left", fontsize=7)
    fig.tight_layout()
    fmt = path.suffix.lstrip(".") or "png"
    try:
        with fileio.atomic_open(path, "wb") as fh:
            fig.savefig(fh, format=fmt, dpi=130)
    finally:
        plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("summary", type=Path)
    ap.add_argument("--plot", type=Path, default=None)
    args = ap.parse_args()
    rows, copies = table(fileio.read_json(args.summary))
    for line in copies:
        print(line)
    for model, gaits in rows.items():
        print(
            f"\n{model}: against the gait shipped before (targets: mean >= {MEAN_TARGET}x, "
            f"p10 >= {P10_TARGET:.0%} of own nominal, nominal >= {NOMINAL_TARGET}x)"
        )
        print(f"  {'gait':<34}{'mean':>7}{'p10':>7}{'nominal':>9}  met")
        for name, r in sorted(gaits.items(), key=lambda kv: -sum(met(kv[1]))):
            print(
                f"  {name:<34}{r['mean']:7.2f}{r['p10']:7.0%}{r['nominal']:9.2f}  "
                f"{sum(met(r))} of 3"
            )
        best = max(sum(met(r)) for r in gaits.values())
        print(f"  {len(gaits)} gaits; the most targets any meets: {best} of 3")
    if args.plot:
        plot(rows, args.plot)
        print(f"\nplot: {args.plot}")


if __name__ == "__main__":
    main()
