"""A run directory: best.json, history.csv and checkpoint.npz, all written atomically.

Chromosomes are stored with ``numpy.packbits`` (8 genes a byte).

The checkpoint holds the whole :class:`RunState` (populations, random generator state, fitness
cache, history, best so far), so ``--resume`` continues exactly where the last finished step
left off and reaches the same result as a run that was never interrupted.
"""

from __future__ import annotations

import csv
import io
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bstool import fileio
from bstool.controllers import save_controller
from bstool.errors import InputError
from bstool.evolve.engine import GAParams, HistoryRow, RunState, Validated
from bstool.evolve.fitness import FitnessCache
from bstool.evolve.problem import Problem
from bstool.evolve.randomize import Randomize
from bstool.robot import robotfile
from bstool.version import __version__

CHECKPOINT = "checkpoint.npz"
BEST = "best.json"
HISTORY = "history.csv"
FORMAT = "bstool.evolve-checkpoint/1"
HISTORY_FIELDS = ["generation", "best", "mean", "population", "evaluations"]
VALIDATION_FIELD = "validation"  # --randomize runs: the best's validation mean (or empty)


def history_csv(rows: list[HistoryRow], validation: bool = False) -> str:
    """history.csv; ``validation`` (a randomized run) adds the validation column."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(HISTORY_FIELDS + ([VALIDATION_FIELD] if validation else []))
    for r in rows:
        line = [r.generation, repr(r.best), repr(r.mean), r.population, r.evaluations]
        if validation:
            line.append("" if r.validation is None else repr(r.validation))
        writer.writerow(line)
    return buf.getvalue()


def read_history(path: str | os.PathLike[str]) -> list[HistoryRow]:
    """Rows of a history.csv; a missing or malformed file is an :class:`InputError`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(
            f"no history file {p}", hint="give directories written by `bstool evolve --out`"
        ) from None
    rows = list(csv.DictReader(io.StringIO(text)))
    if not text.startswith(",".join(HISTORY_FIELDS)):
        raise InputError(f"{p}: expected the header {','.join(HISTORY_FIELDS)}")
    out = []
    for line, r in enumerate(rows, start=2):
        try:
            value = r.get(VALIDATION_FIELD) or None
            out.append(
                HistoryRow(
                    int(r["generation"]),
                    float(r["best"]),
                    float(r["mean"]),
                    r["population"],
                    int(r["evaluations"]),
                    None if value is None else float(value),
                )
            )
        except (TypeError, ValueError) as exc:
            raise InputError(f"{p}:{line}: malformed history row: {exc}") from None
    return out


def save_outputs(state: RunState, out: str | os.PathLike[str], extra: dict[str, Any]) -> None:
    """best.json and history.csv, then the checkpoint (each atomic)."""
    d = Path(out)
    best = state.best_controller(evaluation_settings(extra))
    if best is not None:
        save_controller(best, d / BEST)
    fileio.write_text(d / HISTORY, history_csv(state.history, state.randomize is not None))
    save_checkpoint(state, d / CHECKPOINT, extra)


EVALUATION_KEYS = ("stamp_timed", "period", "timing", "schedule_builds", "randomize", "init")
"""The run's evaluation settings (``extra``) that best.json's ``ga`` also records."""


def evaluation_settings(extra: Mapping[str, Any]) -> dict[str, Any]:
    return {k: extra[k] for k in EVALUATION_KEYS if k in extra}


def save_checkpoint(state: RunState, path: Path, extra: dict[str, Any]) -> None:
    keys, values = state.cache.to_arrays()
    meta = {
        "format": FORMAT,
        "bstool_version": __version__,
        "problem": {
            "model": state.problem.model,
            "legs": state.problem.legs,
            "modules": state.problem.modules,
            "transitions": state.problem.transitions,
        },
        "params": state.params.to_json(),
        "step": state.step,
        "rng": state.rng.bit_generator.state,
        "history": [r.to_json() for r in state.history],
        "best_fitness": state.best_fitness if state.best_row is not None else None,
        "best_name": state.best_name,
        "offspring": state.offspring,
        "offspring_skipped": state.offspring_skipped,
        "cache_evaluations": state.cache.evaluations,
        "cache_hits": state.cache.hits,
        "extra": extra,
    }
    arrays: dict[str, Any] = {  # Any: numpy stubs type **kwargs of savez as allow_pickle
        "meta": np.array(json.dumps(meta)),
        "cache_keys": keys,
        "cache_values": values,
    }
    for name, bits in state.populations.items():
        arrays[f"pop_{name}"] = np.packbits(bits, axis=-1)
    for name, bits in state.best_of.items():
        arrays[f"bestof_{name}"] = np.packbits(bits)
    if state.best_row is not None:
        arrays["best_row"] = np.packbits(state.best_row)
    if state.best_partner is not None:
        arrays["best_partner"] = np.packbits(state.best_partner)
    if state.parasites is not None:
        arrays["parasites"] = state.parasites.astype(np.int16)
    if state.validated is not None:  # --randomize: best.json's candidate
        v = state.validated
        meta["validated"] = {"name": v.name, "validation": v.validation}
        arrays["validated_row"] = np.packbits(v.row)
        if v.partner is not None:
            arrays["validated_partner"] = np.packbits(v.partner)
        arrays["meta"] = np.array(json.dumps(meta))
    with fileio.atomic_open(path, "wb") as fh:
        np.savez(fh, **arrays)


def is_run(directory: str | os.PathLike[str]) -> bool:
    """Whether ``directory`` holds a run of ``bstool evolve``: positively, its checkpoint opens
    and declares this format (a stray ``checkpoint.npz`` of another tool does not count)."""
    path = Path(directory) / CHECKPOINT
    try:
        if not path.is_file():
            return False
        with np.load(path, allow_pickle=False) as npz:
            meta = json.loads(str(npz["meta"]))
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile):
        return False
    return isinstance(meta, dict) and meta.get("format") == FORMAT


def load_checkpoint(out: str | os.PathLike[str]) -> tuple[RunState, dict[str, Any]]:
    """The saved state of the run in directory ``out`` and its ``extra`` settings."""
    path = Path(out) / CHECKPOINT
    if not path.exists():
        raise InputError(
            f"no checkpoint in {out}: {path} does not exist",
            hint="--resume takes a directory written by `bstool evolve --out`",
        )
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
        meta = json.loads(str(data["meta"]))
        if meta.get("format") != FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, expected {FORMAT!r}")
        problem = Problem(**meta["problem"])
        params = GAParams(**meta["params"])
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = meta["rng"]

        def bits(key: str, name: str) -> np.ndarray:
            return np.unpackbits(data[key], axis=-1, count=problem.length(name))

        pops = {n: bits(f"pop_{n}", n) for n in problem.populations}
        state = RunState(problem, params, rng, pops)
        names = [n for n in problem.populations if f"bestof_{n}" in data]
        state.best_of = {n: bits(f"bestof_{n}", n) for n in names}
        state.step = int(meta["step"])
        state.history = [HistoryRow(**r) for r in meta["history"]]
        state.cache = FitnessCache.from_arrays(
            data["cache_keys"], data["cache_values"], meta["cache_evaluations"], meta["cache_hits"]
        )
        if meta["best_fitness"] is not None:
            state.best_fitness = float(meta["best_fitness"])
            state.best_name = meta["best_name"]
            state.best_row = bits("best_row", state.best_name)
            partner = problem.partner_of(state.best_name)
            if partner is not None:
                state.best_partner = bits("best_partner", partner)
        state.offspring = int(meta["offspring"])
        state.offspring_skipped = int(meta["offspring_skipped"])
        if "parasites" in data:
            state.parasites = data["parasites"].astype(np.int16)
        extra = dict(meta.get("extra", {}))
        if extra.get("robot") is not None:
            state.robot = robotfile.from_record(extra["robot"], str(path))
        if extra.get("randomize") is not None:
            state.randomize = Randomize.from_json(extra["randomize"])
        if "validated" in meta:
            name = meta["validated"]["name"]
            partner = problem.partner_of(name)
            state.validated = Validated(
                name,
                bits("validated_row", name),
                None if partner is None else bits("validated_partner", partner),
                float(meta["validated"]["validation"]),
            )
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        raise InputError(
            f"cannot read checkpoint {path}: {exc}", hint="the file is damaged; start a new run"
        ) from None
    return state, extra
