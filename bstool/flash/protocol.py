"""The old name of :mod:`bstool.wire.programming`, kept so ``bstool.flash.protocol`` imports
still work; new code imports ``bstool.wire.programming``."""

from __future__ import annotations

from bstool.wire.programming import *  # noqa: F403
