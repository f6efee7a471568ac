"""``bstool probe``: measure a real stamp's timing and fit the timing model (issue 13 §2).

Library use::

    from bstool.probe import probe
    result = probe("/dev/ttyUSB0")
    bstool.timingfile.dump(result.model, "stamp-timing.json")

:mod:`.program` renders the measurement program, :mod:`.measure` flashes it and times its
markers, :mod:`.fit` turns the times into coefficients. The file format: :mod:`bstool.timingfile`.
"""

from __future__ import annotations

from bstool.probe.measure import ProbeResult, probe

__all__ = ["ProbeResult", "probe"]
