"""How long a campaign has left: each unfinished run's remaining generations at its model's
pace, measured by the campaign itself (DIR/campaign.json: the seconds and generations it spent
on each run). Models differ several-fold (a ca2ddiff step costs about a fifth of a ca1d
generation), so a single generations-per-second rate, as a progress bar would use, is far
off."""

from __future__ import annotations

from collections.abc import Mapping

from bstool.campaign.record import Record


def per_model(models: Mapping[str, str], record: Record) -> dict[str, float]:
    """Seconds per generation of each model (``models``: run name -> model) over the
    generations the campaign timed."""
    seconds: dict[str, float] = {}
    steps: dict[str, int] = {}
    for name, model in models.items():
        entry = record.runs.get(name)
        if entry is None or entry.steps <= 0:
            continue
        seconds[model] = seconds.get(model, 0.0) + entry.wall_s
        steps[model] = steps.get(model, 0) + entry.steps
    return {m: seconds[m] / steps[m] for m in steps}


def seconds_left(
    remaining: Mapping[str, int],
    models: Mapping[str, str],
    pace: Mapping[str, float],
    fallback: float | None = None,
) -> float | None:
    """Seconds for ``remaining`` generations per run: each at its model's ``pace``, a model
    not timed yet at the mean of the others (or ``fallback``, s per generation). None when
    nothing is known about the pace."""
    known = list(pace.values())
    default = sum(known) / len(known) if known else fallback
    total = 0.0
    for name, left in remaining.items():
        rate = pace.get(models[name], default)
        if rate is None:
            return None
        total += max(0, left) * rate
    return total


def text(seconds: float | None) -> str:
    """ "3.2 h", "25 min", or "?" when unknown."""
    if seconds is None:
        return "?"
    return f"{seconds / 3600:.1f} h" if seconds >= 5400 else f"{seconds / 60:.0f} min"
