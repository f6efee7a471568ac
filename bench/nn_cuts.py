"""NN chain wires cut in a running robot (``RobotTwin(cut_at=...)``, ``bstool twin --cut
A-B@S``): each chain wire of leg 2 at a few instants, T = 16, no physics; one JSON line per run
(exact modules of 30 against ``--die B@T_B``, :func:`hil_mock.outage.nn_cut_failures`) and a
summary line.

    python bench/nn_cuts.py BUILD_ROOT [--models nnsin,nnsig] [--instants 4]

BUILD_ROOT/<model> are `bstool compile` outputs.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from bstool.controllers import load_controller
from bstool.moduleid import ModuleId
from hil_mock.outage import nn_cut_reference
from hil_mock.robot import RobotTwin, load_build

T = 16


def run(root: str, model: str, a: ModuleId, b: ModuleId, at: float) -> dict[str, object]:
    build = load_build(f"{root}/{model}")
    twin = RobotTwin(build, physics=False, cut_at={(a, b): at})
    result = twin.run(T, timeout_s=60.0)
    dies, want = nn_cut_reference(twin, load_controller(build.controller_file), T)
    got = result.state_array(build.legs, build.modules, T)
    exact = int(np.all(got == want, axis=0).sum())
    legs, mods = np.nonzero(np.any(got != want, axis=0))
    bad = [ModuleId(int(leg), int(m)).label for leg, m in zip(legs, mods, strict=True)]
    die = {m.label: t for m, t in dies.items()}
    return {"model": model, "cut": f"{a.label}-{b.label}", "at": at, "exact": exact, "bad": bad,
            "die": die, "stalled": len(result.stalled)}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("build_root", help="folder with one `bstool compile` output per model")
    parser.add_argument("--models", default="nnsin,nnsig", help="comma-separated")
    parser.add_argument("--instants", type=int, default=4, help="cut instants in 1.5-4.5 s")
    args = parser.parse_args()
    instants = [round(float(x), 2) for x in np.linspace(1.5, 4.5, args.instants)]
    t0, rows = time.perf_counter(), []
    for model in args.models.split(","):
        for j in range(5):
            for at in instants:
                rows.append(run(args.build_root, model, ModuleId(2, j), ModuleId(2, j + 1), at))
                print(json.dumps(rows[-1]), flush=True)
    exact = sum(r["exact"] == 30 for r in rows)
    lead = [r for r in rows if r["cut"].startswith("L2.M0-")]
    print(f"{exact} of {len(rows)} runs exact ({sum(r['exact'] == 30 for r in lead)} of "
          f"{len(lead)} with the lead's wire cut); {time.perf_counter() - t0:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
