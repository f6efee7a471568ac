"""Time to tokenize a set of PBASIC programs with bstool's tokenizer.

Target (issue 3): the 30 programs `bstool compile` makes tokenize in well under a second.
Without FILES this times the 30 programs of each shipped controller's build (compiled first,
untimed; a CA program is a project of 3 slots) and the 30 shared tokenizer vectors (the 5 that
must fail included: error paths cost time too).

    python bench/tokenize_speed.py [--baseline DIR] [FILE.bsx ...]
    python bench/tokenize_speed.py --scaling

``--scaling`` (also run after the default set) times long tables, the programs users write
(and the inputs that used to take minutes): a LOOKUP list, a DATA list and a DATA table of one
item per line, each at 1x, 2x, 4x and 8x the size (about 9 to 72 KB; the larger ones are
rejected: the slot or the element list is full). Cost must grow linearly with the source:
the figures show time per KB and the ratio to 1x.

``--baseline DIR`` times, side by side in the same run, another copy of the package: DIR must
hold a ``bstool`` folder (e.g. a copy of an older tree: ``cp -r bstool /tmp/old/``). Each
round runs both versions one after the other in fresh processes, so both see the same load;
the figures are the best of the rounds, in CPU time.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

VECTORS = Path(__file__).resolve().parent.parent / "tests" / "vectors" / "tokenizer"
ROUNDS = 5


def _time_once(files: list[Path]) -> tuple[float, float, int]:
    """(wall s, CPU s, slots) of one pass over ``files`` with the importable bstool."""
    from bstool.errors import SourceError
    from bstool.tokenizer import tokenize_file

    start, start_cpu = time.perf_counter(), time.process_time()
    slots = 0
    for path in files:
        try:
            slots += len(tokenize_file(path).slots)
        except SourceError:
            slots += 0  # the must-fail vectors
    return time.perf_counter() - start, time.process_time() - start_cpu, slots


def _worker(files: list[Path]) -> int:
    _time_once(files)  # warm up: imports, regex compilation, file cache
    wall, cpu, slots = _time_once(files)
    print(f"{wall} {cpu} {slots}")
    return 0


def _run_worker(files: list[Path], pythonpath: str | None) -> tuple[float, float, int]:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run(
        [sys.executable, __file__, "--worker", *map(str, files)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    return float(out[0]), float(out[1]), int(out[2])


def _compare(
    files: list[Path], label: str, baseline: Path | None, parser: argparse.ArgumentParser
) -> None:
    """Best-of-ROUNDS times of ``files`` with this tree's bstool (and the baseline's)."""
    here = str(Path(__file__).resolve().parent.parent)
    variants = {"current": here}
    if baseline is not None:
        if not (baseline / "bstool" / "tokenizer").is_dir():
            parser.error(f"{baseline} holds no bstool/tokenizer package")
        variants = {"baseline": str(baseline.resolve()), **variants}
    best: dict[str, tuple[float, float, int]] = {}
    for _ in range(ROUNDS):
        for name, path in variants.items():
            wall, cpu, slots = _run_worker(files, path)
            old = best.get(name)
            best[name] = (min(wall, old[0]), min(cpu, old[1]), slots) if old else (wall, cpu, slots)
    for name, (wall, cpu, slots) in best.items():
        print(
            f"tokenize {label} [{name}]: {len(files)} programs ({slots} slots) in "
            f"{wall * 1000:.1f} ms wall, {cpu * 1000:.1f} ms CPU (best of {ROUNDS}); "
            f"{cpu / len(files) * 1000:.2f} ms CPU per program"
        )
    if "baseline" in best:
        ratio = best["baseline"][1] / best["current"][1]
        print(f"tokenize {label}: current is {ratio:.2f}x the speed of the baseline (CPU)")


HEAD = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"
SCALING = {  # name -> items at 1x -> source
    "LOOKUP list": lambda n: (
        HEAD
        + "x VAR Word\nLOOKUP 0, ["
        + ", ".join(str((i * 7919) % 65536) for i in range(n))
        + "], x\n"
    ),
    "DATA list": lambda n: HEAD + "T DATA " + ", ".join(str(i % 256) for i in range(n)) + "\n",
    "DATA lines": lambda n: HEAD + "".join(f"DATA {i % 256} ' item {i}\n" for i in range(n // 2)),
    # accepted at every size (the whole source is read): a full table and its commentary
    "commented": lambda n: (
        HEAD
        + "".join(f"' rule {i}: neighbours {i % 16} {i % 7}\n" for i in range(n // 4))
        + "T DATA "
        + ", ".join(str(i % 256) for i in range(2000))
        + "\n"
    ),
}
SCALING_ITEMS = 1300  # about 9 KB of source at 1x


def _scaling() -> None:
    """Time vs source size for long tables at 1x, 2x, 4x, 8x (best of ROUNDS, CPU time)."""
    from bstool.errors import SourceError
    from bstool.tokenizer import tokenize_source

    for name, make in SCALING.items():
        base = None
        for factor in (1, 2, 4, 8):
            text = make(SCALING_ITEMS * factor)
            best = float("inf")
            outcome = "accepted"
            for _ in range(ROUNDS):
                start = time.process_time()
                try:
                    tokenize_source(text, "table.bsx")
                except SourceError as exc:
                    outcome = f"rejected ({exc.code})"
                best = min(best, time.process_time() - start)
            kb = len(text) / 1024
            base = base or best / kb
            print(
                f"scaling {name:11s} {factor}x: {kb:5.1f} KB in {best * 1000:6.2f} ms CPU, "
                f"{best / kb * 1000:.3f} ms/KB ({best / kb / base:.2f}x the 1x rate), {outcome}"
            )
    print("scaling: target: ms/KB flat (linear cost), no table over 1 s")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="folder holding another bstool package")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--scaling", action="store_true", help="only the long-table figures")
    parser.add_argument("files", nargs="*", type=Path)
    args = parser.parse_args(argv)
    if args.worker:
        return _worker(args.files)
    if args.scaling:
        _scaling()
        return 0
    if args.files:
        _compare(args.files, "files", args.baseline, parser)
    else:
        from bstool.builtin import MODELS, builtin_controller
        from bstool.compile import compile_controller

        with tempfile.TemporaryDirectory() as tmp:
            for model in MODELS:
                out = Path(tmp) / model
                compile_controller(builtin_controller(model), out)
                mains = sorted(out.glob("modules/*/main.bsx"))
                _compare(mains, f"{model} build", args.baseline, parser)
        vectors = sorted(next(p for p in d.glob("*.bsx")) for d in VECTORS.iterdir() if d.is_dir())
        _compare(vectors, "vectors", args.baseline, parser)
    print("tokenize: target: 30 programs well under 1 s")
    _scaling()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
