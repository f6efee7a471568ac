"""A measured timing file (``bstool.timing/1``, ``bstool probe``) as the twin's timing model.

:func:`use` makes the file's coefficients the nominal timing of every virtual stamp made
afterwards in this process (the per-module perturbations, ``--timing-scale`` etc., still apply
on top): the statement cost ``base + per_bit × token bits``, RUN, and the PAUSE, PULSOUT and
SERIN-timeout units. Serial bit times stay the baudmode's (the file's SEROUT item time is
reported, not applied: a stamp's UART follows its resonator, which the units already carry).
``bstool twin --timing F`` and ``python -m hil_mock serve --timing-model F`` call it; so does
anything else that runs the twin's interpreter in the same process (the stamp-timed simulator).
"""

from __future__ import annotations

import os

from bstool import timingfile
from bstool.timingfile import TimingModel
from hil_mock.stamp import timing


def use(model: TimingModel | None) -> None:
    """The twin's timing model from now on (None: back to the estimate)."""
    if model is None:
        timing.use_model(*timing.ESTIMATE)
        return
    timing.use_model(
        round(model.base_us.value * 1000),
        round(model.per_bit_us.value * 1000),
        round(model.run_us.value * 1000),
        round(model.pause_unit_ms.value * 1_000_000),
        round(model.pulsout_unit_us.value * 1000),
        round(model.serin_unit_ms.value * 1_000_000),
    )


def use_file(path: str | os.PathLike[str] | None) -> TimingModel | None:
    """Load ``path`` (an InputError if it is not a good timing file) and :func:`use` it."""
    if path is None:
        return None
    model = timingfile.load(path)
    use(model)
    return model
