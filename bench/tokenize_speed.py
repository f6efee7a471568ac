"""Time to tokenize a set of PBASIC programs with bstool's tokenizer.

Target (issue 3): the 30 programs `bstool compile` makes tokenize in well under a second.
Until `bstool compile` exists this uses the 30 shared tokenizer vectors (the 5 that must fail
included: error paths cost time too). Usage: python bench/tokenize_speed.py [FILE.bsx ...]
"""

from __future__ import annotations

import sys

# This file is named like the standard library's `tokenize`; keep its folder off the import
# path so `import tokenize` (used by dataclasses via inspect) finds the real module.
sys.path[:] = [p for p in sys.path if not p.endswith("bench")]

import time  # noqa: E402
from pathlib import Path  # noqa: E402

from bstool.errors import SourceError  # noqa: E402
from bstool.tokenizer import tokenize_file  # noqa: E402

VECTORS = Path(__file__).resolve().parent.parent / "tests" / "vectors" / "tokenizer"


def main(argv: list[str]) -> int:
    files = [Path(a) for a in argv] or sorted(
        next(p for p in d.glob("*.bsx")) for d in VECTORS.iterdir() if d.is_dir()
    )
    best = best_cpu = float("inf")
    slots = 0
    for _ in range(5):
        start, start_cpu = time.perf_counter(), time.process_time()
        slots = 0
        for path in files:
            try:
                slots += len(tokenize_file(path).slots)
            except SourceError:
                slots += 0  # the must-fail vectors
        best = min(best, time.perf_counter() - start)
        best_cpu = min(best_cpu, time.process_time() - start_cpu)
    print(
        f"tokenize: {len(files)} programs ({slots} slots) in {best * 1000:.1f} ms wall, "
        f"{best_cpu * 1000:.1f} ms CPU (best of 5)"
    )
    print(f"tokenize: {best / len(files) * 1000:.2f} ms per program; target: 30 programs < 1 s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
