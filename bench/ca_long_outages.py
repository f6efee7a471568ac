"""CA long outages (docs/link-redesign.md §2.4): a reset of a lead (0.0), a middle (2.3) and a
last module (2.5) for 2, 3 and 5 s at 10 instants 1.0..3.0 s, T = 10, no physics; one JSON line
per run (exact modules of 30; stalled: modules other than the reset one that did not make T;
rejoined: the reset module was back in step by the end; S/L/D; the reference used) and a
summary line. NN builds run the same way (``--models nnsin,nnsig -T 20``: NN transitions are
shorter, so the module is back well before the end).

    python bench/ca_long_outages.py BUILD_ROOT [--models ca1d,ca2dsing,ca2ddiff] [-T 10]
        [--instants 10]

BUILD_ROOT/<model> are `bstool compile` outputs.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from bstool.controllers import load_controller
from hil_mock.outage import compared_states, outage_reference, outages
from hil_mock.perturb import Perturbation, Reset
from hil_mock.robot import RobotTwin, load_build

MODULES = ("0.0", "2.3", "2.5")
OFF_S = (2.0, 3.0, 5.0)


def run(root: str, model: str, module: str, off: float, at: float, T: int) -> dict[str, object]:
    build = load_build(f"{root}/{model}")
    twin = RobotTwin(build, physics=False, perturb=Perturbation(resets=(Reset(module, at, off),)))
    result = twin.run(T)
    outs = outages(twin)
    want = outage_reference(load_controller(build.controller_file), T, outs)
    got = compared_states(result.states, want, outs)
    exact = sum(seq[: T + 1] == want[:, m.leg, m.module].tolist() for m, seq in got.items())
    o = outs[0] if outs else None
    kind = "?" if o is None else ("S" if not o.long else ("L" if o.consistent else "D"))
    others = [m for m in result.stalled if str(m) != module]
    return {"model": model, "module": module, "off": off, "at": at, "exact": int(exact),
            "stalled": len(others), "rejoined": module not in {str(m) for m in result.stalled},
            "kind": kind, "ref": o.reference_text() if o else None}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("build_root", help="folder with one `bstool compile` output per model")
    parser.add_argument("--models", default="ca1d,ca2dsing,ca2ddiff", help="comma-separated")
    parser.add_argument("-T", "--transitions", type=int, default=10)
    parser.add_argument("--instants", type=int, default=10, help="power-off instants in 1-3 s")
    args = parser.parse_args()
    instants = [round(float(x), 2) for x in np.linspace(1.0, 3.0, args.instants)]
    t0, rows = time.perf_counter(), []
    for model in args.models.split(","):
        for module in MODULES:
            for off in OFF_S:
                for at in instants:
                    rows.append(run(args.build_root, model, module, off, at, args.transitions))
                    print(json.dumps(rows[-1]), flush=True)
    exact = sum(r["exact"] == 30 for r in rows)
    stalled = sum(bool(r["stalled"]) for r in rows)
    joining = sum(not r["rejoined"] for r in rows)
    print(f"{exact} of {len(rows)} runs exact; {stalled} with a module other than the reset one "
          f"stalled; {joining} ended with the reset module still off or joining (compared as "
          f"dead); {time.perf_counter() - t0:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
