"""A walk through bstool's Python API, one notebook cell per ``# %%`` block.

Run it as a script (small sizes by default, a few seconds) or paste the cells into Jupyter:

    python examples/notebook_walkthrough.py [--pop 4 --gens 2 --transitions 10] [--keep DIR]

It loads the shipped controller, prints its states, simulates it, evaluates a small batch,
runs a tiny evolution with a progress callback, compiles a build, tokenizes one module's
program, flashes that module into a virtual stamp over ``bstwin://`` and runs the 30-stamp
twin. ``--summary FILE`` writes the figures as JSON (the tests read it). Reference: docs/api.md.
"""

# %% setup
from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path
from typing import Any

import bstool.api as bst
from bstool.errors import InputError

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--model", default="ca1d", help="model to evolve (default ca1d)")
parser.add_argument("--pop", type=int, default=4)
parser.add_argument("--gens", type=int, default=2)
parser.add_argument("--transitions", type=int, default=10, help="per simulation / evaluation")
parser.add_argument("--seed", type=int, default=1)
parser.add_argument("--fitness", default="physics", choices=["physics", "toy"])
parser.add_argument("--twin-transitions", type=int, default=3, help="0: skip the twin")
parser.add_argument("--keep", type=Path, help="work in this folder instead of a temporary one")
parser.add_argument("--summary", type=Path, help="write the figures to this JSON file")
args = parser.parse_args()

work = args.keep or Path(tempfile.mkdtemp(prefix="bstool-walkthrough-"))
work.mkdir(parents=True, exist_ok=True)
T = args.transitions
summary: dict[str, Any] = {"work": str(work)}

# %% 1. load and validate a controller
ctrl = bst.builtin_controller("nnsin")  # or bst.load_controller("run/best.json")
print(
    f"controller: {ctrl.model}, {ctrl.legs} legs x {ctrl.modules} modules, hash {ctrl.hash()[:8]}"
)
try:
    bst.load_controller({"format": "bstool.controller/1", "model": "nnsin"})
except InputError as exc:  # every user mistake is a bstool.errors type with a hint
    print(f"rejected:   {exc}")

# %% 2. its state sequence R^0..R^T (and with module 2.3 failed)
seq = bst.states(ctrl, transitions=T)
hurt = bst.states(ctrl, transitions=T, failed=["2.3"])
print(f"states:     shape {seq.shape}; leg 0 at R^T: {seq[-1, 0].tolist()}")
summary["states_shape"] = list(seq.shape)

# %% 3. simulate one run, then a batch on threads
res = bst.simulate(ctrl, transitions=T)
print(f"simulate:   {res.distance * 100:.2f} cm after {res.transitions} transitions")
healthy, failed = bst.evaluate([seq, hurt])
cm = [r.distance * 100 for r in (healthy, failed)]
print(f"evaluate:   healthy {cm[0]:.2f} cm, 2.3 failed {cm[1]:.2f} cm")
summary["distance_m"] = res.distance
summary["batch_m"] = [healthy.distance, failed.distance]

# %% 4. a tiny evolution with a progress callback (Ctrl-C leaves a resumable run folder)
seen: list[bst.Generation] = []


def on_generation(g: bst.Generation) -> None:
    seen.append(g)
    best, mean = bst.fitness_text(g.best, g.fitness), bst.fitness_text(g.mean, g.fitness)
    print(f"  generation {g.step}/{g.total_steps}: best {best}, mean {mean}")


result = bst.evolve(
    args.model,
    pop=args.pop,
    gens=args.gens,
    seed=args.seed,
    transitions=T,
    fitness=args.fitness,
    out=work / "run",
    on_generation=on_generation,
)
print(f"evolve:     best {result.fitness_text} -> {result.best_json} ({len(result.history)} rows)")
summary["evolve"] = {
    "fitness": result.fitness,
    "generations": len(seen),
    "history_rows": len(result.history),
    "best_json": str(result.best_json),
    "completed": result.completed,
}

# %% 5. compile the shipped controller into a build folder
build = bst.compile(ctrl, work / "build")
print(f"compile:    {len(build.modules)} modules -> {build.out_dir}")
summary["modules"] = len(build.modules)

# %% 6. tokenize one module's program
program = build.out_dir / "modules" / "L0.M0" / "main.bsx"
project = bst.tokenize(program)
image = project.slots[0]
print(
    f"tokenize:   {program.name}: {image.program_bytes} program bytes, {len(image.records)} records"
)
summary["tokenized_equal"] = image.eeprom == (program.parent / "slot0.eeprom").read_bytes()

# %% 7. flash that module into a virtual stamp (hil_mock's bstwin:// serial URL)
import hil_mock  # noqa: E402,F401 - registers bstwin://
from bstool.flash import FAST  # noqa: E402 - an instant twin needs no real waits

report = bst.flash(build.out_dir, "bstwin://walkthrough-L0.M0", module="0.0", timing=FAST)
print(f"flash:      L0.M0 {report.summary()}; announcement ok: {report.announcement_ok}")
summary["flash_ok"] = report.announcement_ok

# %% 8. run the twin: 30 virtual stamps driving the MuJoCo robot, compared with the reference
if args.twin_transitions:
    from bstool import buildfile
    from hil_mock.session import TwinOptions, run_twin

    tt = args.twin_transitions
    twin = run_twin(buildfile.load(build.out_dir), TwinOptions(transitions=tt))
    print(f"twin:       {twin.result.distance * 100:.2f} cm; states equal to bst.states: {twin.ok}")
    summary["twin_states_equal"] = bool(twin.ok)

if args.summary:
    args.summary.write_text(json.dumps(summary, indent=1) + "\n")
if args.keep is None:  # a temporary folder: give it back (--keep DIR to look at the files)
    shutil.rmtree(work)
