"""Every wire of every lead cut from power-up, on stamps up to 3x slower than the timing model
(issue 28 §2): the twin's own verdict (`bstool twin --cut A-B --timing-scale F --no-physics`).

    python bench/lead_cuts.py [--models ca1d,ca2dsing,...] [--scales 1,1.5,2,2.5,3] [-T 20]
                              [--legs 0,1,2,3,4] [--workers 2] [--build-root DIR] [--json]

The shipped controllers (bstool/data/controllers/) are compiled once each into a temporary
folder (or read from BUILD_ROOT/<model>). The wires cut are every wire with a lead at one end:
to the next module (L.0-L.1), the ring closure (L.0-L.5, CA), the lead-to-lead wires (2-D CA)
and the bypass (L.0-L.2, NN). Each run is compared with the reference the twin picks for a cut
(docs/twin.md "--cut"): CA each end reads the other's R^0; NN every module but B as with
``--fail B``, B as with its upstream failed. A row per model and timing scale: runs exact,
runs in which some module stalled, and the running period with the cut against the period of
the same build without it over the same modules and transitions (the mean over the periods
that began once every module had moved,
:meth:`hil_mock.twin_result.TwinResult.running_period_stats`: the start-up, which a wire silent
from power-up lengthens by the power-up window, is reported apart). A summary line closes it.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from bstool.builtin import MODELS, builtin_controller
from bstool.compile import compile_controller
from bstool.moduleid import ModuleId
from hil_mock.perturb import Perturbation
from hil_mock.robot import load_build
from hil_mock.session import TwinOptions, run_twin

RATIO_LIMIT = 1.2  # the bound on the period with a cut against without


@dataclass(frozen=True)
class Run:
    model: str
    scale: float
    cut: tuple[ModuleId, ModuleId] | None
    exact: bool
    stalled: int
    period: float  # the running period (s)
    moving: float  # when every module had made its first transition (s)
    spans: tuple[tuple[str, int, float], ...] = ()  # (module, period index, s) of running periods

    @property
    def label(self) -> str:
        return "none" if self.cut is None else f"{self.cut[0].label}-{self.cut[1].label}"


def lead_wires(root: Path, legs: list[int]) -> list[tuple[ModuleId, ModuleId]]:
    """Every wire of the build with a lead of ``legs`` at one end, in manifest order."""
    links = load_build(root).manifest.links
    return [(w.master, w.slave) for w in links
            if any(m.module == 0 and m.leg in legs for m in (w.master, w.slave))]  # fmt: skip


def run_one(root: str, model: str, scale: float, cut: tuple[ModuleId, ModuleId] | None,
            transitions: int) -> Run:  # fmt: skip
    options = TwinOptions(
        transitions=transitions,
        cut=[cut] if cut else [],
        physics=False,
        perturb=Perturbation(timing_scale=scale),
    )
    report = run_twin(load_build(root), options)
    result = report.result
    period, _ = result.running_period_stats()
    spans = tuple(
        (mid.label, len(result.periods[mid]) - len(ps) + i, p)
        for mid, ps in result.running_periods.items()
        for i, p in enumerate(ps)
    )
    return Run(model, scale, cut, report.ok, len(result.stalled), period, result.moving_s, spans)


def same_transitions_ratio(run: Run, base: Run) -> float:
    """The cut run's running period against the uncut run's over the same modules and
    transitions. A module cut off from power-up may start seconds late, leaving only the last
    few transitions in the running window, and a gait's period moves from transition to
    transition with its pulse widths (nnsig 2026-12-07, timing scale 1.5: 0.43-0.57 s), so the
    uncut run's whole-run mean is not the yardstick for those few."""
    ref = {(m, i): p for m, i, p in base.spans}
    pairs = [(p, ref[m, i]) for m, i, p in run.spans if (m, i) in ref]
    if not pairs:
        return run.period / base.period
    return sum(p for p, _ in pairs) / sum(q for _, q in pairs)


def sweep(args: argparse.Namespace, roots: dict[str, Path]) -> list[Run]:
    legs = [int(x) for x in args.legs.split(",")]
    jobs = []
    for model in args.models.split(","):
        cuts: list[tuple[ModuleId, ModuleId] | None] = [None, *lead_wires(roots[model], legs)]
        for scale in (float(x) for x in args.scales.split(",")):
            jobs += [(str(roots[model]), model, scale, cut, args.transitions) for cut in cuts]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(run_one, *job) for job in jobs]
        runs = []
        for f in futures:
            runs.append(f.result())
            if args.json:
                r = runs[-1]
                print(json.dumps({"model": r.model, "scale": r.scale, "cut": r.label,
                                  "exact": r.exact, "stalled": r.stalled,
                                  "period": round(r.period, 4), "moving": round(r.moving, 2)}),
                      flush=True)  # fmt: skip
    return runs


def table(runs: list[Run]) -> list[str]:
    lines = ["| model | timing scale | exact | stalled | period without cut (s) | "
             "period with a cut: median / largest (s) | "
             "largest ratio: same transitions (largest against the whole run) | "
             "wire of the first |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    keys = sorted({(r.model, r.scale) for r in runs}, key=lambda k: (MODELS.index(k[0]), k[1]))
    for model, scale in keys:
        rows = [r for r in runs if (r.model, r.scale) == (model, scale)]
        base = next(r for r in rows if r.cut is None)
        cut = [r for r in rows if r.cut is not None]
        periods = sorted(r.period for r in cut)
        worst = max(cut, key=lambda r: same_transitions_ratio(r, base))
        lines.append(
            f"| {model} | {scale:g} | {sum(r.exact for r in cut)}/{len(cut)} | "
            f"{sum(r.stalled > 0 for r in cut)} | {base.period:.3f} | "
            f"{periods[len(periods) // 2]:.3f} / {periods[-1]:.3f} | "
            f"{same_transitions_ratio(worst, base):.2f} ({periods[-1] / base.period:.2f}) | "
            f"{worst.label} |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", default=",".join(MODELS), help="comma-separated")
    parser.add_argument("--scales", default="1,1.5,2,2.5,3", help="timing scales, comma-separated")
    parser.add_argument("-T", "--transitions", type=int, default=20)
    parser.add_argument("--legs", default="0,1,2,3,4", help="the leads whose wires are cut")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--build-root", help="BUILD_ROOT/<model>: compiled builds to use")
    parser.add_argument("--json", action="store_true", help="also one JSON line per run")
    args = parser.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        roots = {}
        for model in args.models.split(","):
            if args.build_root:
                roots[model] = Path(args.build_root) / model
            else:
                roots[model] = Path(tmp) / model
                compile_controller(builtin_controller(model), roots[model])
        runs = sweep(args, roots)
    print(f"T = {args.transitions}, no physics; runs per cell: every lead wire cut from power-up")
    print("\n".join(table(runs)))
    cut = [r for r in runs if r.cut is not None]
    bases = {(r.model, r.scale): r for r in runs if r.cut is None}
    ratio = max(same_transitions_ratio(r, bases[r.model, r.scale]) for r in cut)
    whole = max(r.period / bases[r.model, r.scale].period for r in cut)
    exact = sum(r.exact for r in cut)
    stalled = sum(r.stalled > 0 for r in cut)
    ok = exact == len(cut) and not stalled and ratio <= RATIO_LIMIT
    print(f"{exact} of {len(cut)} cut runs exact, {stalled} with a stall, largest period ratio "
          f"{ratio:.2f} over the same transitions (limit {RATIO_LIMIT}; {whole:.2f} against the "
          f"uncut run's whole-run mean): {'OK' if ok else 'FAIL'}; "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
