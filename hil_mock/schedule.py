"""The twin's scheduler: the modules share one virtual time line.

A conservative scheduler always advances the stamp that is furthest behind, and never past the
horizon of a stamp wired to it, so a byte a module sends reaches exactly the neighbours that
were listening when its start bit began. :func:`advance_globally` is the simpler scheduler it
replaced (never past the horizon of any stamp in the robot): the same records, 2-3x slower;
tests/test_twin_scheduler.py and ``bench/twin.py`` run the two side by side.
"""

from __future__ import annotations

import heapq

from bstool.moduleid import ModuleId
from hil_mock.stamp import NEVER, Stamp, Status

CHUNK_STEPS = 5
"""MuJoCo steps per scheduling chunk (10 ms at the 2 ms step): shorter than one servo frame."""


class Scheduler:
    """Stamp scheduling, a mixin of :class:`hil_mock.robot.RobotTwin`."""

    stamps: dict[ModuleId, Stamp]
    wires: dict[tuple[ModuleId, int], list[tuple[ModuleId, int]]]
    _killed: bool
    _scheduling: tuple[list[Stamp], list[list[int]]] | None = None  # until the stamps change

    def _advance_stamps(self, limit_ns: int) -> None:
        """Run every stamp up to ``limit_ns``, always the one furthest behind first, and never
        past the horizon of a stamp it is wired to (only those can send it a byte, drive a pin it
        reads or hear one of its bytes), so it may run ahead of the rest of the robot. The
        horizons sit in a heap; a step changes only the stepped stamp's and its peers'."""
        stamps, peers, heap, known = self._scheduling_heap()
        self._killed = False
        heappop, heappush = heapq.heappop, heapq.heappush
        while heap:
            if self._killed:  # a module died or came back in the last step
                stamps, peers, heap, known = self._scheduling_heap()
                self._killed = False
            h1, best = heap[0]
            if h1 != known[best]:  # stale: the stamp was pushed again since
                heappop(heap)
                continue
            if h1 >= limit_ns:
                return
            heappop(heap)
            stamp = stamps[best]
            near = peers[best]
            if stamp.status is Status.WAITING:
                stamp.expire_wait()
            else:
                bound = limit_ns
                for j in near:
                    h = known[j]
                    if h < bound:
                        bound = h
                stamp.run_until(bound if bound > h1 else h1 + 1)
            h = known[best] = stamp.horizon
            heappush(heap, (h, best))
            for j in near:  # a byte it sent may have woken or moved them
                h = stamps[j].horizon
                if h != known[j]:
                    known[j] = h
                    heappush(heap, (h, j))

    def _scheduling_heap(
        self,
    ) -> tuple[list[Stamp], list[list[int]], list[tuple[int, int]], list[int]]:
        if self._killed or self._scheduling is None:
            self._scheduling = self._scheduling_lists()
        stamps, peers = self._scheduling
        known = [s.horizon for s in stamps]
        heap = [(h, i) for i, h in enumerate(known)]
        heapq.heapify(heap)
        return stamps, peers, heap, known

    def _scheduling_lists(self) -> tuple[list[Stamp], list[list[int]]]:
        """The running stamps, and for each the indices of the running stamps it is wired to."""
        stamps = list(self.stamps.values())
        near: dict[ModuleId, set[ModuleId]] = {}
        for (mid, _), ends in self.wires.items():
            near.setdefault(mid, set()).update(peer for peer, _ in ends)
        index = {mid: i for i, mid in enumerate(self.stamps)}
        peers = [
            [index[p] for p in sorted(near.get(mid, ())) if p in index and p != mid]
            for mid in self.stamps
        ]
        return stamps, peers


def advance_globally(twin: Scheduler, limit_ns: int) -> None:
    """The reference: the stamp furthest behind runs up to the second-smallest horizon of the
    whole robot (a scan of every stamp per step; the scheduler before 2026-12-03)."""
    stamps = list(twin.stamps.values())
    twin._killed = False
    while True:
        if twin._killed:
            stamps = list(twin.stamps.values())
            twin._killed = False
        best: Stamp | None = None
        h1 = h2 = NEVER
        for stamp in stamps:
            h = stamp.horizon
            if h < h1:
                h2, h1, best = h1, h, stamp
            elif h < h2:
                h2 = h
        if best is None or h1 >= limit_ns:
            return
        if best.status is Status.WAITING:
            best.expire_wait()
        else:
            best.run_until(min(limit_ns, max(h2, h1 + 1)))
