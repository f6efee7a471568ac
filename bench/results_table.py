"""Summarise ``bstool report`` outputs (report.json) into the Markdown tables of docs/results.md.

    python bench/results_table.py REPORT_DIR [REPORT_DIR ...] [--figures DIR]

Every entry of every report is one evolved controller (one model, one seed). Prints a table
per run, a table per model (mean ± standard deviation over its runs) and, where a report was
made with ``--multi-failures``, the median degree of mobility against the number of failed
modules. ``--figures DIR`` also draws the distance-against-transition curves of the first
report's controllers on one figure (paper Fig. 19) and copies its paths, failures and
multiple-failure figures there. Only reads reports; the long runs are in bench/experiments.sh.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

MODELS = ["nnsin", "nnsig", "ca1d", "ca2dsing", "ca2ddiff"]


def load(dirs: list[Path]) -> list[dict[str, Any]]:
    entries = []
    for d in dirs:
        data = json.loads((d / "report.json").read_text())
        T = data["transitions"]
        for e in data["entries"]:
            plain = np.array(e["extrapolation"]["plain"], dtype=float)
            reinit = np.array(e["extrapolation"]["reinit"], dtype=float)
            e["report"] = d.name
            e["T"] = T
            e["d_T"] = float(plain[T])
            e["d_end_plain"] = float(plain[-1])
            e["d_end_reinit"] = float(reinit[-1])
            e["peak_at"] = int(np.argmax(plain))
            e["end_over_T"] = float(plain[-1] / plain[T]) if plain[T] > 0 else float("nan")
            entries.append(e)
    return entries


def fmt(values: list[float], scale: float = 1.0, digits: int = 1) -> str:
    arr = np.array(values, dtype=float) * scale
    if arr.size == 1:
        return f"{arr[0]:.{digits}f}"
    return f"{arr.mean():.{digits}f} ± {arr.std(ddof=1):.{digits}f}"


def per_run(entries: list[dict[str, Any]]) -> str:
    end = len(entries[0]["extrapolation"]["plain"]) - 1
    head = (
        f"| run | model | d_30 (cm) | keep ≥80 % | keep 100 % | mean M_D (%) | peak at | "
        f"d_{end} plain (cm) | d_{end} re-init (cm) | max dev (cm) | sway (cm) | rot. spread |"
    )
    rows = [head, "|" + "---|" * 12]
    for e in sorted(entries, key=lambda e: (MODELS.index(e["model"]), e["name"])):
        f = e["faults"]
        rows.append(
            f"| {e['report']}/{e['name']} | {e['model']} | {e['distance'] * 100:.1f} | "
            f"{f['keep_80']} | {f['keep_100']} | {e['mean_mobility']:.1f} | {e['peak_at']} | "
            f"{e['d_end_plain'] * 100:.1f} | {e['d_end_reinit'] * 100:.1f} | "
            f"{e['shape']['max_deviation'] * 100:.1f} | {e['shape']['sway'] * 100:.2f} | "
            f"{e['rotation']['relative_range']:.0e} |"
        )
    return "\n".join(rows)


def per_model(entries: list[dict[str, Any]]) -> str:
    end = len(entries[0]["extrapolation"]["plain"]) - 1
    head = (
        f"| model | runs | d_30 (cm) | keep ≥80 % | keep 100 % | mean M_D (%) | peak at | "
        f"d_{end} / d_30 plain | d_{end} / d_30 re-init | max dev (cm) | sway (cm) |"
    )
    rows = [head, "|" + "---|" * 11]
    for model in MODELS:
        mine = [e for e in entries if e["model"] == model]
        if not mine:
            continue
        rows.append(
            f"| {model} | {len(mine)} | {fmt([e['distance'] for e in mine], 100)} | "
            f"{fmt([e['faults']['keep_80'] for e in mine])} | "
            f"{fmt([e['faults']['keep_100'] for e in mine])} | "
            f"{fmt([e['mean_mobility'] for e in mine])} | "
            f"{np.median([e['peak_at'] for e in mine]):.0f} | "
            f"{fmt([e['end_over_T'] for e in mine], digits=2)} | "
            f"{fmt([e['d_end_reinit'] / e['d_T'] for e in mine], digits=2)} | "
            f"{fmt([e['shape']['max_deviation'] for e in mine], 100)} | "
            f"{fmt([e['shape']['sway'] for e in mine], 100, 2)} |"
        )
    return "\n".join(rows)


def multi(entries: list[dict[str, Any]]) -> str | None:
    with_multi = [e for e in entries if e.get("multi_failures")]
    if not with_multi:
        return None
    ks = sorted(with_multi[0]["multi_failures"], key=int)
    rows = [
        "| controller | " + " | ".join(f"K = {k}" for k in ks) + " |",
        "|" + "---|" * (len(ks) + 1),
    ]
    for e in with_multi:
        cells = [f"{e['multi_failures'][k]['median']:.0f}" for k in ks]
        rows.append(f"| {e['report']}/{e['name']} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def figures(report: Path, entries: list[dict[str, Any]], out: Path) -> None:
    from bstool.experiments.plots import plot_distance_curves

    out.mkdir(parents=True, exist_ok=True)
    mine = [e for e in entries if e["report"] == report.name]
    curves = {e["name"]: np.array(e["extrapolation"]["plain"]) for e in mine}
    title = "Distance from the start against transition (plain)"
    plot_distance_curves(out / "extrapolation.png", curves, mine[0]["T"], title=title)
    curves = {e["name"]: np.array(e["extrapolation"]["reinit"]) for e in mine}
    title = f"Re-initialised to R^0 every {mine[0]['T']} transitions"
    plot_distance_curves(out / "extrapolation-reinit.png", curves, mine[0]["T"], title=title)
    for name in ("paths.png", "faults.png", "multi.png"):
        if (report / name).exists():
            shutil.copyfile(report / name, out / name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reports", type=Path, nargs="+", help="bstool report output folders")
    parser.add_argument("--figures", type=Path, help="write the figures of the first report here")
    args = parser.parse_args()
    entries = load(args.reports)
    if args.figures:
        figures(args.reports[0], entries, args.figures)
    print("## Per model (mean ± sd over runs)\n")
    print(per_model(entries))
    print("\n## Per run\n")
    print(per_run(entries))
    table = multi(entries)
    if table:
        print("\n## Median M_D (%) with K random modules failed\n")
        print(table)


if __name__ == "__main__":
    main()
