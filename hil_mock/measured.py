"""A measured timing file (``bstool.timing/1``, ``bstool probe``) as the twin's timing model.

The model is a value passed to what makes the stamps' clocks (``RobotTwin(timing=...)``,
``TwinOptions.timing``, ``extract_schedule(timing=...)``, ``StampClock(model=...)``), never a
process-wide setting: its statement cost ``base + per_bit × token bits``, RUN, and the PAUSE,
PULSOUT and SERIN-timeout units become every stamp's nominal timing (the per-module
perturbations, ``--timing-scale`` etc., still apply on top; :func:`hil_mock.stamp.timing.of`).
``bstool twin --timing F``, ``bstool simulate --build B --timing F`` and
``python -m hil_mock serve --timing-model F`` load it here.
"""

from __future__ import annotations

import os

from bstool import timingfile
from bstool.timingfile import TimingModel


def load(path: str | os.PathLike[str] | None) -> TimingModel | None:
    """The timing model of ``path`` (None: None, the estimate); an InputError if it is not a
    good timing file."""
    return None if path is None else timingfile.load(path)
