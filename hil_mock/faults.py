"""Fault injection on the twin: modules failed from power-up and modules dying mid-run."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping

from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module
from hil_mock.body import ServoTrack
from hil_mock.stamp import Stamp, Status
from hil_mock.twin_result import ModuleRecord


def failed_modules(failed: Iterable[ModuleId | str], legs: int, modules: int) -> set[ModuleId]:
    return {m if isinstance(m, ModuleId) else parse_module(m, legs, modules) for m in failed}


def dying_modules(
    die: Mapping[ModuleId, int] | Mapping[str, int] | None,
    failed: set[ModuleId],
    legs: int,
    modules: int,
) -> dict[ModuleId, int]:
    """Module -> the transition T at which it dies (checked: T >= 0, not failed as well)."""
    out: dict[ModuleId, int] = {}
    for key, when in (die or {}).items():
        mid = key if isinstance(key, ModuleId) else parse_module(key, legs, modules)
        if int(when) < 0:
            raise InputError(f"module {mid} cannot die at transition {when}: T must be >= 0")
        if mid in failed:
            raise InputError(f"module {mid} is both failed from power-up and dying at {when}")
        out[mid] = int(when)
    return out


class Faults:
    """Dying modules, a mixin of :class:`hil_mock.robot.RobotTwin`."""

    die: dict[ModuleId, int]
    died: dict[ModuleId, int]
    records: dict[ModuleId, ModuleRecord]
    stamps: dict[ModuleId, Stamp]
    servos: dict[ModuleId, ServoTrack]
    limp_failed: bool
    _nn: bool
    _killed: bool
    _readers: dict[ModuleId, tuple[Callable[[Stamp], int], Callable[[Stamp], int]]]

    def _dies_at_pulse(self, mid: ModuleId, stamp: Stamp, after: bool) -> bool:
        """Whether a dying module stops at this servo pulse (``after``: once it went out).

        The module dies once its servo shows S^T and its neighbours have had S^T. A CA program
        shows S^T, then exchanges it, then looks up S^(T+1): it stops at the first pulse of
        S^(T+1), before it goes out (tn has changed T + 1 times; nothing happens on a link
        between the lookup and that pulse). An NN program relays S^T downstream first and then
        shows it: it stops right after the first pulse of S^T (tn has changed T times)."""
        when = self.die.get(mid)
        if when is None:
            return False
        rec = self.records[mid]
        if self._nn:
            return after and len(rec.states) == when + 1
        return (
            not after
            and len(rec.states) == when + 1
            and self._readers[mid][1](stamp) != rec.last_tn
        )

    def _kill(self, mid: ModuleId, stamp: Stamp, t_ns: int) -> None:
        stamp.status = Status.STOPPED  # for good: ends the running run_until at once
        stamp.brk = True
        del self.stamps[mid]
        self.died[mid] = t_ns
        self.servos[mid].limp = self.limp_failed
        self._killed = True
