"""Progress bars of the experiment commands: tqdm on stderr, off with ``-q`` or when stderr
is not a terminal (``BSTOOL_PROGRESS=1`` forces them on, e.g. under a pager or in tests)."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from tqdm import tqdm

#: set to "1" to show bars even when stderr is not a terminal, "0" to never show them
ENV = "BSTOOL_PROGRESS"


def enabled(quiet: bool) -> bool:
    """Whether a bar is drawn: never with ``quiet``; else on a terminal, or as ENV says."""
    if quiet:
        return False
    forced = os.environ.get(ENV)
    if forced in ("0", "1"):
        return forced == "1"
    return sys.stderr.isatty()


class Bar:
    """``bar(k)`` advances by k steps (from worker threads too); ``bar.total(n)`` sets the end."""

    def __init__(self, t: tqdm) -> None:
        self._t = t

    def __call__(self, k: int = 1) -> None:
        self._t.update(k)

    def total(self, n: int) -> None:
        self._t.total = n
        self._t.refresh()

    def describe(self, text: str) -> None:
        self._t.set_description_str(text)


@contextmanager
def bar(desc: str, total: int | None, *, quiet: bool, unit: str = "run") -> Iterator[Bar]:
    """A bar of ``total`` steps on stderr (drawn only when :func:`enabled`)."""
    with tqdm(
        total=total,
        desc=desc,
        unit=unit,
        file=sys.stderr,
        disable=not enabled(quiet),
        leave=False,
        dynamic_ncols=True,
    ) as t:
        yield Bar(t)
