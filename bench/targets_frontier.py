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
    """One gait's three ratios against the gait shipped before (``base``)."""
    return {
        "mean": figures["mean"] / base["mean"],
        "p10": figures["p10"] / figures["nominal"] if figures["nominal"] > 0 else 0.0,
        "nominal": figures["nominal"] / base["nominal"],
    }


def met(r: dict[str, float]) -> list[bool]:
    """Which of the three targets (mean, p10, nominal) ``r`` meets."""
    return [r["mean"] >= MEAN_TARGET, r["p10"] >= P10_TARGET, r["nominal"] >= NOMINAL_TARGET]


def table(summary: dict[str, Any]) -> dict[str, dict[str, dict[str, float]]]:
    """Per model, per gait (the baseline left out), its ratios."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for model, entry in summary.items():
        runs = entry["runs"]
        base = runs.get("shipped")
        if base is None:
            raise SystemExit(f"{model}: no 'shipped' gait in the summary to compare with")
        out[model] = {name: ratios(f, base) for name, f in runs.items() if name != "shipped"}
    return out


def _group(name: str) -> str:
    """The legend group of a gait: its campaign (the part of its name before ':')."""
    return name.partition(":")[0] if ":" in name else name


def plot(rows: dict[str, dict[str, dict[str, float]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = sorted({_group(n) for gaits in rows.values() for n in gaits})
    colours = {g: plt.get_cmap("tab10")(i % 10) for i, g in enumerate(groups)}
    fig, axes = plt.subplots(1, len(rows), figsize=(5.5 * len(rows), 4.6), squeeze=False)
    for ax, (model, gaits) in zip(axes[0], rows.items(), strict=True):
        right = max(1.4, max(r["nominal"] for r in gaits.values()) + 0.05)
        ax.fill_between(
            [NOMINAL_TARGET, right],
            P10_TARGET,
            1.0,
            color="tab:green",
            alpha=0.15,
            label="nominal and p10 targets",
        )
        shown: set[str] = set()
        for name, r in gaits.items():
            group = _group(name)
            colour = colours[group]
            ax.scatter(
                r["nominal"],
                r["p10"],
                s=45,
                edgecolors=[colour],
                facecolors=[colour] if r["mean"] >= MEAN_TARGET else "none",
                label=None if group in shown else group,
            )
            shown.add(group)
        ax.set_xlabel("nominal distance / the gait shipped before")
        ax.set_ylabel("10th percentile / own nominal")
        ax.set_title(f"{model} (filled: box mean >= {MEAN_TARGET}x as well)")
        ax.set_ylim(0, 1.0)
        ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp, dpi=130)
    tmp.replace(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("summary", type=Path)
    ap.add_argument("--plot", type=Path, default=None)
    args = ap.parse_args()
    rows = table(fileio.read_json(args.summary))
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
