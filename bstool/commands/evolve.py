"""``bstool evolve``: the paper's GA (or §3.4 co-evolution) into a run directory."""

from __future__ import annotations

import os
import secrets
import sys
import time
from pathlib import Path
from typing import Any

import click

from bstool.controllers.reference import MODELS
from bstool.errors import InputError
from bstool.evolve.checkpoint import BEST, CHECKPOINT, load_checkpoint, save_outputs
from bstool.evolve.engine import (
    MAX_COEVOL_GENERATION,
    GAParams,
    HistoryRow,
    RunState,
    default_gens,
    default_pm,
    new_run,
    run,
)
from bstool.evolve.fitness import Evaluator, EvaluatorFactory, PhysicsFitness, ToyFitness
from bstool.evolve.problem import Problem
from bstool.evolve.scoring import ROBUST_MODES, parasite_cells, parse_k

_CELLS = Problem("ca1d").legs * Problem("ca1d").modules  # the robot bstool evolve builds

_FIXED_ON_RESUME = (
    "model",
    "pop",
    "pc",
    "pm",
    "transitions",
    "coevol_gens",
    "seed",
    "fitness",
    "robust",
    "coevolve_faults",
    "parasites",
    "parasite_k",
)
DEFAULT_PARASITES = 4  # Q + 1 = 5 runs per host, the physics budget of --robust with n = 5
DEFAULT_PARASITE_K = "1..2"


def _cpus() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def factory_for(kind: str, problem: Problem, workers: int) -> EvaluatorFactory:
    if kind == "toy":
        return ToyFitness()
    return PhysicsFitness(legs=problem.legs, modules=problem.modules, workers=workers)


@click.command("evolve")
@click.argument("model", type=click.Choice(MODELS), required=False, metavar="MODEL")
@click.option("--pop", type=click.IntRange(min=2), help="POP_SIZE (default 50).")
@click.option(
    "--gens",
    type=click.IntRange(min=1),
    help="MAX_GEN (default 100; ca2ddiff: outer loops, default 3). With --resume: extend to N.",
)
@click.option("--pc", type=click.FloatRange(0, 1), help="Crossover probability P_C (default 0.8).")
@click.option(
    "--pm",
    type=click.FloatRange(0, 1),
    help="Per-gene mutation probability P_M (default 0.0002 CA, 0.01 NN).",
)
@click.option(
    "--transitions", type=click.IntRange(min=1), help="MAX_TRANS per evaluation (default 30)."
)
@click.option(
    "--coevol-gens",
    type=click.IntRange(min=1),
    help=f"ca2ddiff: MAX_COEVOL_GENERATION (default {MAX_COEVOL_GENERATION}).",
)
@click.option("--seed", type=click.IntRange(min=0), help="Random seed (default: a random one).")
@click.option("--workers", type=click.IntRange(min=1), help="Physics threads (default: all CPUs).")
@click.option("--out", "out", type=click.Path(file_okay=False), help="Run directory to create.")
@click.option(
    "--resume",
    type=click.Path(file_okay=False),
    help="Continue the run in this directory from its last checkpoint.",
)
@click.option(
    "--cluster",
    metavar="ADDRESS",
    help="Evaluate on a Dask scheduler, e.g. tcp://host:8786 (pip install 'bstool[cluster]').",
)
@click.option(
    "--fitness",
    type=click.Choice(["physics", "toy"]),
    help="physics (MuJoCo, default) or toy (a cheap stand-in to try the pipeline).",
)
@click.option(
    "--robust",
    type=click.Choice(ROBUST_MODES),
    is_flag=False,
    flag_value="mean",
    help="Score each candidate over its n leg rotations: mean (default) or worst distance.",
)
@click.option(
    "--coevolve-faults",
    is_flag=True,
    default=None,
    help="Co-evolve a population of parasites (sets of failed modules) that hurt the hosts.",
)
@click.option(
    "--parasites",
    type=click.IntRange(min=2),
    help=f"--coevolve-faults: parasite population size (default {DEFAULT_PARASITES}).",
)
@click.option(
    "--parasite-k",
    metavar="K|A..B",
    help=f"--coevolve-faults: failed modules per parasite (default {DEFAULT_PARASITE_K}).",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
def command(
    model: str | None,
    out: str | None,
    resume: str | None,
    workers: int | None,
    cluster: str | None,
    quiet: bool,
    **options: Any,
) -> None:
    """Evolve a MODEL controller (ca1d, ca2dsing, ca2ddiff, nnsig, nnsin) with the paper's GA.

    Fitness is the disc's displacement after MAX_TRANS transitions (eq. 6). The run directory
    gets best.json (a controller file), history.csv and a checkpoint after every generation;
    Ctrl-C stops cleanly and `--resume DIR` continues to the same result.

    --robust scores a candidate over its n leg rotations; --coevolve-faults scores hosts against
    a co-evolving population of module failures (paper §6). See docs/evolution.md.
    """
    options["model"] = model
    options["coevolve_faults"] = True if options.get("coevolve_faults") else None
    if options.get("parasite_k") is not None:
        options["parasite_k"] = list(parse_k(options["parasite_k"], _CELLS))
    if resume is not None:
        if out is not None and Path(out) != Path(resume):
            raise InputError("give either --out DIR (new run) or --resume DIR, not both")
        state, extra = _resume(resume, options)
        directory = Path(resume)
    else:
        if model is None:
            raise InputError("missing MODEL", hint=f"one of: {', '.join(MODELS)}")
        if out is None:
            raise InputError("missing --out DIR", hint="the run directory to write results to")
        directory = Path(out)
        if (directory / CHECKPOINT).exists():
            raise InputError(
                f"{directory} already holds a run",
                hint=f"continue it with --resume {directory}, or choose another --out",
            )
        state, extra = _new(model, options)
    # On a cluster each Dask worker thread runs one simulation at a time (start workers with
    # --nthreads = cores); locally the batch evaluator uses --workers threads.
    threads = workers or (1 if cluster else _cpus())
    factory = factory_for(extra["fitness"], state.problem, threads)
    evaluator: Evaluator
    closer: Any = None
    if cluster:
        from bstool.evolve.cluster import DaskEvaluator

        evaluator = closer = DaskEvaluator(cluster, factory)
    else:
        evaluator = factory.build()
        closer = evaluator if hasattr(evaluator, "close") else None
    try:
        _run(state, evaluator, directory, extra, quiet)
    finally:
        if closer is not None:
            closer.close()


def _new(model: str, options: dict[str, Any]) -> tuple[RunState, dict[str, Any]]:
    def pick(name: str, default: Any) -> Any:
        return default if options.get(name) is None else options[name]

    coevolve = bool(options.get("coevolve_faults"))
    if not coevolve:
        for name in ("parasites", "parasite_k"):
            if options.get(name) is not None:
                flag = "--" + name.replace("_", "-")
                raise InputError(
                    f"{flag} only applies with --coevolve-faults",
                    hint=f"add --coevolve-faults, or drop {flag}",
                )
    elif options.get("robust") is not None:
        raise InputError(
            "--robust and --coevolve-faults do not combine",
            hint="choose one scoring: rotations (--robust) or failures (--coevolve-faults)",
        )
    default_k = parse_k(DEFAULT_PARASITE_K, _CELLS)
    params = GAParams(
        pop=pick("pop", 50),
        gens=pick("gens", default_gens(model)),
        pc=pick("pc", 0.8),
        pm=pick("pm", default_pm(model)),
        transitions=pick("transitions", 30),
        coevol_gens=pick("coevol_gens", MAX_COEVOL_GENERATION),
        seed=pick("seed", secrets.randbits(32)),
        robust=options.get("robust"),
        parasites=pick("parasites", DEFAULT_PARASITES) if coevolve else 0,
        parasite_k=tuple(pick("parasite_k", default_k)),
    )
    problem = Problem(model, transitions=params.transitions)
    return new_run(problem, params), {"fitness": pick("fitness", "physics")}


def _resume(directory: str, options: dict[str, Any]) -> tuple[RunState, dict[str, Any]]:
    state, extra = load_checkpoint(directory)
    p = state.params
    saved = {
        **p.to_json(),
        "model": state.problem.model,
        "robust": p.robust,
        "coevolve_faults": p.coevolve_faults or None,
        "parasites": p.parasites or None,
        "parasite_k": list(p.parasite_k) if p.coevolve_faults else None,
        **extra,
    }
    for name in _FIXED_ON_RESUME:
        given = options.get(name)
        if given is not None and given != saved.get(name):
            flag = "MODEL" if name == "model" else "--" + name.replace("_", "-")
            before = saved.get(name)
            raise InputError(
                f"{flag} is {given!r} but the run in {directory} was started with {before!r}"
                if before is not None
                else f"the run in {directory} was started without {flag}",
                hint="a resumed run keeps its settings; only --gens may be raised",
            )
    gens = options.get("gens")
    if gens is not None:
        done = state.step // (state.total_steps // state.params.gens)
        if gens < done:
            raise InputError(f"--gens {gens} is less than the {done} generations already done")
        state.params = GAParams(**{**state.params.to_json(), "gens": gens})
    return state, extra


def _mode(state: RunState) -> str:
    p = state.params
    if p.robust is not None:
        return f" --robust {p.robust}"
    return f" --coevolve-faults ({p.parasites} parasites)" if p.coevolve_faults else ""


def _run(
    state: RunState, evaluator: Evaluator, directory: Path, extra: dict[str, Any], quiet: bool
) -> None:
    from tqdm import tqdm

    bar = tqdm(
        total=state.total_steps,
        initial=state.step,
        desc=f"evolve {state.problem.model}{_mode(state)}",
        unit="gen",
        file=sys.stderr,
        disable=quiet or not sys.stderr.isatty(),
        dynamic_ncols=True,
    )
    start, paid0 = time.perf_counter(), state.cache.evaluations

    def after_step(st: RunState, row: HistoryRow) -> None:
        save_outputs(st, directory, extra)
        rate = (st.cache.evaluations - paid0) / max(time.perf_counter() - start, 1e-9)
        bar.set_postfix(
            {
                "gen": f"{row.population}:{row.generation}",
                "best": f"{row.best:.4g}",
                "mean": f"{row.mean:.4g}",
                "eval/s": f"{rate:.1f}",
            },
            refresh=False,
        )
        bar.update(1)

    try:
        if state.step == 0 and not (directory / CHECKPOINT).exists():
            save_outputs(state, directory, extra)  # a run directory exists from the start
        run(state, evaluator, after_step)
    except KeyboardInterrupt:
        bar.close()
        click.echo(
            f"Interrupted after {state.step} of {state.total_steps} generations; everything "
            f"so far is saved in {directory}. Continue with: bstool evolve --resume {directory}",
            err=True,
        )
        raise  # bstool.cli.main ends with "Interrupted." and exit status 130
    bar.close()
    if not quiet:
        s = state.stats()
        skipped = s["offspring_skipped"] / s["offspring"] if s["offspring"] else 0.0
        click.echo(
            f"best fitness {state.best_fitness:.6g} -> {directory / BEST}\n"
            f"evaluations {s['evaluations']}, cache hits {s['cache_hits']}, "
            f"offspring skipped {s['offspring_skipped']}/{s['offspring']} ({skipped:.1%})"
        )
        if state.parasites is not None:
            last = next(r for r in reversed(state.history) if r.population == "parasite")
            worst = parasite_cells(state.parasites[0], state.problem.modules)
            click.echo(
                f"most harmful parasite: {' '.join(f'{i}.{j}' for i, j in worst)} failed "
                f"(takes {last.best:.1%} of the hosts' distance on average)"
            )
