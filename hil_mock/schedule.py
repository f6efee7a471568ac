"""The twin's scheduler: the modules share one virtual time line.

A conservative scheduler always advances the stamp that is furthest behind, and never past the
next stamp's horizon, so a byte a module sends reaches exactly the neighbours that were
listening when its start bit began.
"""

from __future__ import annotations

from bstool.moduleid import ModuleId
from hil_mock.stamp import NEVER, Stamp, Status

CHUNK_STEPS = 5
"""MuJoCo steps per scheduling chunk (10 ms at the 2 ms step): shorter than one servo frame."""


class Scheduler:
    """Stamp scheduling, a mixin of :class:`hil_mock.robot.RobotTwin`."""

    stamps: dict[ModuleId, Stamp]
    _killed: bool

    def _advance_stamps(self, limit_ns: int) -> None:
        """Run every stamp up to ``limit_ns``, always the one furthest behind first."""
        stamps = list(self.stamps.items())
        self._killed = False
        while True:
            if self._killed:  # a module died in the last step
                stamps = list(self.stamps.items())
                self._killed = False
            best: tuple[ModuleId, Stamp] | None = None
            h1 = h2 = NEVER
            for item in stamps:
                h = item[1].horizon
                if h < h1:
                    h2, h1, best = h1, h, item
                elif h < h2:
                    h2 = h
            if best is None or h1 >= limit_ns:
                return
            stamp = best[1]
            if stamp.status is Status.WAITING:
                stamp.expire_wait()
            else:
                stamp.run_until(min(limit_ns, max(h2, h1 + 1)))
