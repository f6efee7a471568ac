"""One-way wires on every wire of a leg, both directions, from power-up and in a running robot
(issue 28 §3): the twin's own verdict (`bstool twin --cut 'A>B[@S]' --no-physics`).

    python bench/one_way_sweep.py [--models nnsin,nnsig,...] [--leg 2] [--at 0,2.5,4] [-T 14]
                                  [--workers 2] [--build-root DIR] [--json]

The shipped controllers (bstool/data/controllers/) are compiled once each into a temporary
folder (or read from BUILD_ROOT/<model>). Every wire with an end in leg LEG (its chain, its
bypass wires for NN, the ring closure for ca1d, the lead-to-lead wires for the 2-D models)
loses the bytes of one of its ends, A>B for both orders of its ends, from power-up (S = 0) and
from each S of --at. Each run is compared with the reference the twin picks for a one-way wire
(that of the same wire cut, docs/twin.md). A row per model: runs exact, runs in which some
module stalled, and the runs that failed by name; a summary line closes it.
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
from hil_mock.robot import load_build
from hil_mock.session import TwinOptions, run_twin


@dataclass(frozen=True)
class Run:
    model: str
    lost: tuple[ModuleId, ModuleId]  # A's bytes to B are lost
    at: float
    exact: bool
    stalled: int

    @property
    def label(self) -> str:
        when = "" if self.at <= 0 else f"@{self.at:g}"
        return f"{self.lost[0].label}>{self.lost[1].label}{when}"


def leg_wires(root: Path, leg: int) -> list[tuple[ModuleId, ModuleId]]:
    """Every wire of the build with an end in ``leg``, in manifest order."""
    links = load_build(root).manifest.links
    return [(w.master, w.slave) for w in links if leg in (w.master.leg, w.slave.leg)]


def run_one(root: str, model: str, lost: tuple[ModuleId, ModuleId], at: float, T: int) -> Run:
    options = TwinOptions(transitions=T, one_way={lost: at}, physics=False)
    report = run_twin(load_build(root), options)
    return Run(model, lost, at, bool(report.ok), len(report.result.stalled or ()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--leg", type=int, default=2)
    ap.add_argument("--at", default="0,2.5,4", help="instants the wire goes one-way (0: power-up)")
    ap.add_argument("-T", "--transitions", type=int, default=14)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--build-root", type=Path, default=None)
    ap.add_argument("--json", action="store_true", help="print every run as JSON")
    args = ap.parse_args()
    models = args.models.split(",")
    instants = [float(s) for s in args.at.split(",")]
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        roots = {}
        for model in models:
            root = (args.build_root or Path(tmp)) / model
            if not (root / "manifest.json").exists():
                compile_controller(builtin_controller(model), root)
            roots[model] = root
        jobs = [
            (str(roots[m]), m, lost, at, args.transitions)
            for m in models
            for a, b in leg_wires(roots[m], args.leg)
            for lost in ((a, b), (b, a))
            for at in instants
        ]
        with ProcessPoolExecutor(args.workers) as pool:
            runs = list(pool.map(run_one, *zip(*jobs, strict=True)))
    if args.json:
        print(json.dumps([{"model": r.model, "one_way": r.label, "exact": r.exact,
                           "stalled": r.stalled} for r in runs], indent=1))  # fmt: skip
        return
    print(f"{'model':<10}{'runs':>6}{'exact':>7}{'stalled':>9}  not exact")
    for model in models:
        mine = [r for r in runs if r.model == model]
        bad = [r.label for r in mine if not r.exact]
        stalled = sum(1 for r in mine if r.stalled)
        exact = len(mine) - len(bad)
        print(f"{model:<10}{len(mine):>6}{exact:>7}{stalled:>9}  {' '.join(bad) or '-'}")
    total = sum(r.exact for r in runs)
    print(f"{total} of {len(runs)} runs exact, {time.perf_counter() - start:.0f} s "
          f"(leg {args.leg}, T = {args.transitions}, from {args.at} s)")  # fmt: skip


if __name__ == "__main__":
    main()
