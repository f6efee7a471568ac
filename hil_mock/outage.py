"""A ``--reset`` outage read from the twin's record: was the module waited for (short) or did
its neighbours go on without it (long), and if long, the reference it is compared with.

A neighbour N of the reset module c waits for c's state in one transition W_N: the one it was
showing at the power-off, or the next (when it still got c's state for that one). Of the two,
W_N is the one that lasted longer after the power-off (a wait for a silent neighbour against an
ordinary transition; both observed, no timing estimate). N holds c's state of T_N (CA: W_N − 1,
N waited for S^(W_N); NN: W_N, N waited for S^(W_N + 1) from upstream; only c's downstream
neighbours read its state). c's record restarts at the transition it rejoined at
(:meth:`hil_mock.robot.RobotTwin._rejoin`). The outage was **long** (its neighbours went on
without it) when a neighbour left W_N before c booted again, or when c came back past the last
state it had shown, or with another state than it had shown there (CA: it took the state its
neighbours held for it), or, for an NN non-lead (which shows eq. 11 on the REQ it rejoins with
at once, R^(T2 + 1)), at a T2 past the state its downstream held. The reference is then
``states(failed_at={c: T}, rejoin={c: T2})`` (docs/controllers.md "Rejoin"); otherwise the
healthy one. If the T_N differ (a power cut between c's exchanges of one transition): CA, per
link, T the latest and ``held={c: {N: T_N}}`` for each reader N that went on with an earlier
one (a neighbour that waited reads the state c rejoins with); NN, T the earliest. The rejoin
is per link too (CA): a reader that went on reads its held state up to and including the
transition in which it sent c its WELCOME (it entered that one holding c dead, so it does not
wait for c's state there), c's own from the next on: ``held={c: {N: (T_N, T2_N)}}`` with T2_N
that transition + 1, read from the twin's wires (the WELCOME headers each module sent,
:attr:`hil_mock.links.Links.welcomes`). docs/twin.md, "Which reference a reset is compared with".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.moduleid import ModuleId
from bstool.wire import link
from hil_mock.twin_result import NS, OFF_STATE

RobotTwin = Any  # a hil_mock.robot.RobotTwin after its run (it imports this module's users)


@dataclass(frozen=True)
class Outage:
    """One power-off of a reset module and what its neighbours did about it."""

    module: ModuleId
    off_s: float
    booted_s: float | None  # None: still off at the end of the run
    held: dict[ModuleId, int] = field(default_factory=dict)  # N -> T_N, for N that went on
    rejoin: int | None = None  # T2 (None: not back within the run)
    rejoined_at: int | None = None  # where its record restarts (T2, NN non-lead T2 + 1)
    # CA: the neighbours that read c's state (its rule's readers; a wire peer may not be one):
    # each is compared reading the state it held (per link); NN: empty, compared with the earliest
    reads: frozenset[ModuleId] = frozenset()
    # N -> T_N for the N that left their wait before c booted (CA: before they WELCOMEd c; a
    # waiting one reads the state c rejoins with: its REQ is answered with it)
    went_on: dict[ModuleId, int] = field(default_factory=dict)
    # CA: N -> T2_N for the N that went on and then WELCOMEd c: the transition N was in when it
    # sent its first WELCOME after c booted, + 1 (N reads c's state again from there)
    until: dict[ModuleId, int] = field(default_factory=dict)
    # CA: T_R < T when c came back with an older state than the S^T it showed, the one its
    # neighbours held for it of T_R (its join takes the state of a neighbour that went on)
    rejoin_with: int | None = None

    @property
    def long(self) -> bool:
        return bool(self.held)

    @property
    def consistent(self) -> bool:
        """Every neighbour that went on held c's state of the same transition."""
        return len(set(self.held.values())) <= 1

    @property
    def per_link(self) -> bool:
        return bool(self.reads)

    @property
    def failed_at(self) -> int | None:
        """T: the transition whose state the neighbours held; if they differ, CA: the latest (c
        showed it, each other reader is given its own by :attr:`links`), NN: the earliest."""
        if not self.held:
            return None
        return max(self.held.values()) if self.per_link else min(self.held.values())

    @property
    def links(self) -> dict[ModuleId, tuple[int, int | None]]:
        """CA: reader N -> (T_N, T2_N) for the readers that went on and read a state of their
        own: an earlier one than ``failed_at``, or theirs past c's rejoin T2 (T2_N > T2 + 1);
        T2_N None: until T2 (``states(held={c: links})``). With ``rejoin_with`` T_R, a reader
        that waited for a state earlier than S^T reads S^(T_R), the one c came back with."""
        t = self.failed_at
        if t is None:
            return {}
        out: dict[ModuleId, tuple[int, int | None]] = {}
        for n, tn in sorted(self.went_on.items()):
            until = self.until.get(n) if self.rejoin is not None else None
            if until == self.rejoin:
                until = None
            # T_N = T with T2_N = T2 + 1 reads S^T in T2, which c still shows there: no change
            later = until is not None and self.rejoin is not None and until > self.rejoin + 1
            # with rejoin_with the reference shows S^(T_R) from T + 1 to every reader without a
            # view of its own, so one that went on with S^T needs its view too (traced
            # 2026-12-04: ca1d 2.3 off 4 s at 1.62 s, 2.2 read its S^3 until 7)
            kept = self.rejoin_with is not None and tn == t
            if n in self.reads and (tn < t or later or kept):
                out[n] = (tn, until)
        if self.rejoin_with is not None:
            # a reader that waited for a state c had not sent it yet (T_N < T) gets the one c
            # rejoins with, S^(T_R): it reads that until c's rejoin (traced 2026-12-03)
            for n, tn in sorted(self.held.items()):
                if n in self.reads and n not in self.went_on and tn < t:
                    out[n] = (self.rejoin_with, None)
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "module": str(self.module),
            "off_s": self.off_s,
            "booted_s": self.booted_s,
            "long": self.long,
            "held": {str(m): t for m, t in self.held.items()},
            "failed_at": self.failed_at,
            "held_by": {str(m): t for m, (t, _) in self.links.items()},
            "held_until": {str(m): u for m, (_, u) in self.links.items() if u is not None},
            "rejoin": self.rejoin,
            "rejoin_with": self.rejoin_with,
            "reference": self.reference_text(),
        }

    def reference_text(self) -> str:
        if not self.long:
            return "healthy (waited for)"
        ref = f"--fail-at {self.module.label}@{self.failed_at}"
        for n, (tn, until) in self.links.items():
            span = "" if until is None else f"..{until}"
            ref += f" --held-by {n.label}={self.module.label}@{tn}{span}"
        if self.rejoin is not None:
            ref += f" --rejoin {self.module.label}@{self.rejoin}"
        if self.rejoin_with is not None:
            ref += f" --rejoin-with {self.module.label}@{self.rejoin_with}"
        if self.links:
            ref += f" (per link: the others read S^{self.failed_at})"
        elif not self.consistent:
            held = ", ".join(f"{m.label} S^{t}" for m, t in sorted(self.held.items()))
            how = "the latest" if self.per_link else "the earliest"
            ref += f" (neighbours disagree, compared with {how}: {held})"
        return ref


def outages(twin: RobotTwin) -> list[Outage]:
    """Every power-off of the run, in time order."""
    out = []
    lag = 0 if twin._nn else 1
    for mid, offs in twin.perturb.offs.items():
        boots = twin.perturb.boots.get(mid, [])
        rec = twin.records[mid]
        for k, off_s in enumerate(offs):
            booted = boots[k] if k < len(boots) else None
            # NN: c shows S^t once every master wire TOOK it (protocol/link.md §4.6), so its
            # downstream had its states up to the last one it showed before the power-off
            before_off = rec.before[k] if k < len(rec.before) else rec.states
            had = len(before_off) - 1 if twin._nn else -1
            until = booted if twin._nn else None
            waits = {
                n: w
                for n in readers(twin, mid)
                if (w := _wait(twin.records[n].times_ns, off_s, until, had))
            }
            back = math.inf if booted is None else booted * NS
            # CA: N went on when it left its wait before it WELCOMEd c (a dead-limit can fire
            # after c booted, before c's JOIN reached N); NN, or no WELCOME: before c booted
            welcomed = {} if twin._nn else _first_welcomes(twin, mid, back)
            went_on = {n: w - lag for n, (w, left) in waits.items() if left < welcomed.get(n, back)}
            reads = frozenset() if twin._nn else ca_readers(twin, mid)
            if k >= len(rec.rejoined):  # not back (or still joining) at the end of the run
                out.append(Outage(mid, off_s, booted, went_on, reads=reads, went_on=went_on))
                continue
            at = rec.rejoined[k]
            before = rec.before[k]
            if twin._nn and mid.module > 0:
                # an NN non-lead shows eq. 11 on the REQ it rejoins with at once: that state is
                # R^(T2 + 1) of the reference, the held one R^T2 was never shown
                t2 = at - 1
                held = {n: w for n, (w, _) in waits.items() if w < t2}
            else:  # long: it rejoined past what it had shown, or not with the state it showed
                shown = at < len(before) and before[at] == rec.states[at]
                held = {} if shown else {n: w - lag for n, (w, _) in waits.items() if w - lag < at}
                t2 = at
            held = {**went_on, **held}
            until = {n: _transition_at(twin, n, welcomed[n]) + 1 for n in went_on if n in welcomed}
            older = None if twin._nn or not held else _older(held, before, rec.states, at)
            out.append(
                Outage(
                    mid, off_s, booted, held, t2 if held else None, at, reads, went_on, until, older
                )
            )
    return sorted(out, key=lambda o: o.off_s)


def _older(
    held: Mapping[ModuleId, int], before: Sequence[int], states: Sequence[int], at: int
) -> int | None:
    """T_R: the latest of the transitions its neighbours held c's state of, earlier than the
    latest (T), whose state (as c showed it then) c came back with at ``at``; None when it came
    back with S^T, or with a state none of them held."""
    t = max(held.values())
    if at >= len(states) or t >= len(before) or before[t] == states[at]:
        return None
    older = [n for n in set(held.values()) if n < t and before[n] == states[at]]
    return max(older, default=None)


def _first_welcomes(twin: RobotTwin, mid: ModuleId, booted_ns: float) -> dict[ModuleId, int]:
    """N -> when N sent ``mid`` its first WELCOME after ``mid`` booted (ns)."""
    out: dict[ModuleId, int] = {}
    for sender, receiver, start in sorted(twin.welcomes, key=lambda w: w[2]):
        if receiver == mid and start >= booted_ns and sender not in out:
            out[sender] = start
    return out


def _transition_at(twin: RobotTwin, mid: ModuleId, when_ns: int) -> int:
    """The transition ``mid`` was in at ``when_ns``: the last state it showed by then."""
    times = twin.records[mid].times_ns
    return max((i for i, t in enumerate(times) if 0 <= t <= when_ns), default=0)


def nn_cut_failures(
    twin: RobotTwin, cuts_at: Mapping[frozenset[ModuleId], float] | None = None
) -> dict[ModuleId, int]:
    """NN: a chain wire j - (j + 1) cut in a running robot (``cut_at``) is j + 1 failing at the
    last transition it took before the cut: it hears nobody upstream, holds that state (its
    next state follows only from the held upstream states) and j's bypass feeds j + 2 with it
    held. T: the last transition it showed before it could pace on its own (PaceTicks of
    silence after the cut). A cut bypass changes nothing."""
    pace_ns = link.NN.pace_ticks * link.NN_TICK_MS * 1_000_000 if link.NN.pace_ticks else 0
    out: dict[ModuleId, int] = {}
    timed = twin.cut_at_ns if cuts_at is None else {p: round(s * NS) for p, s in cuts_at.items()}
    for pair, at_ns in timed.items():
        a, b = sorted(pair)
        if a.leg == b.leg and b.module - a.module == 1:
            out[b] = _transition_at(twin, b, at_ns + pace_ns)
    return out


def nn_cut_reference(
    twin: RobotTwin, ctrl: Controller, transitions: int
) -> tuple[dict[ModuleId, int], np.ndarray]:
    """After a run with NN chain wires cut (``cut_at``): the downstream ends as failing
    modules (:func:`nn_cut_failures`) and the reference R^0..R^T they make."""
    dies = nn_cut_failures(twin)
    return dies, ctrl.states(transitions, failed_at=dies)


def readers(twin: RobotTwin, mid: ModuleId) -> list[ModuleId]:
    """The modules wired to ``mid`` that read its state (NN: only downstream ones)."""
    peers = {p for (m, _), ends in twin.wires.items() if m == mid for p, _ in ends}
    if twin._nn:
        peers = {p for p in peers if p.leg == mid.leg and p.module > mid.module}
    return sorted(peers)


def ca_readers(twin: RobotTwin, mid: ModuleId) -> frozenset[ModuleId]:
    """The CA modules whose rule reads ``mid``'s state (eq. 4–5, 7–8)."""
    from bstool.controllers.reference import ca_neighbours

    b = twin.build
    model = b.manifest.controller.model
    return frozenset(
        ModuleId(i, j)
        for i in range(b.legs)
        for j in range(b.modules)
        if (mid.leg, mid.module) in ca_neighbours(model, b.legs, b.modules, i, j)
    )


def _wait(
    times_ns: list[int], off_s: float, booted_s: float | None, had: int = -1
) -> tuple[int, float] | None:
    """(W_N, when N left it, ns) of a neighbour with these transition times: of the transition it
    showed at the power-off (NN: or ``had``, below) and the next, the one that lasted longer
    after it. With ``booted_s`` (NN) only the time until the boot counts: after it comes the
    rejoin, not a wait for the module, and an NN leg's transition after a long outage can
    outlast the dead-limit wait before it (CA's join is told apart by its WELCOMEs instead).
    ``had`` (NN): the last transition the module showed before the power-off; N took its states
    up to that one, so it waited in ``had`` at the earliest (N in W waits for S^(W + 1)): a
    transition N left on a state it already had is no wait (traced 2026-12-07: nnsig lead off
    0.1 s at 2 s, 0.1 showed S^4 at 2.055 s on the S^4 the lead had shown at 1.987 s; both spans
    were cut by the boot, and the longer of the two was that ordinary transition). A ``had``
    that N never showed in the run (N behind at the end, or off itself then) leaves the rule by
    lengths alone."""
    off = off_s * NS
    back = math.inf if booted_s is None else booted_s * NS
    shown = [i for i, t in enumerate(times_ns) if 0 <= t <= off]
    if not shown:
        return None
    s = shown[-1]
    if s < had < len(times_ns) and times_ns[had] >= 0:
        s = had

    def end(w: int) -> float:
        return times_ns[w + 1] if w + 1 < len(times_ns) and times_ns[w + 1] >= 0 else math.inf

    def waited(w: int) -> float:
        return min(end(w), back) - max(times_ns[w], off) if w < len(times_ns) else -math.inf

    w = max((s, s + 1), key=waited)
    return w, end(w)


def outage_reference(
    ctrl: Controller,
    transitions: int,
    outs: Sequence[Outage],
    failed: Sequence[ModuleId] = (),
    failed_at: Mapping[ModuleId, int] | None = None,
) -> np.ndarray:
    """``bstool states`` with the run's failures (``failed``, ``failed_at``: ``--fail``,
    ``--die``) and each long outage as ``failed_at`` T + ``rejoin`` T2, CA with ``held`` for the
    readers that held an earlier state (the first outage of a module; a short one changes
    nothing)."""
    dead = dict(failed_at or {})
    rejoin: dict[ModuleId, int] = {}
    older: dict[ModuleId, int] = {}
    held: dict[ModuleId, dict[ModuleId, int | tuple[int, int]]] = {}
    for o in outs:
        if o.long and o.failed_at is not None and o.module not in dead:
            dead[o.module] = o.failed_at
            if o.rejoin_with is not None and o.rejoin is not None and o.rejoin > o.failed_at:
                older[o.module] = o.rejoin_with
            if o.links:
                held[o.module] = {
                    n: tn if until is None else (tn, until) for n, (tn, until) in o.links.items()
                }
            if o.rejoin is not None:
                rejoin[o.module] = o.rejoin
    return ctrl.states(
        transitions,
        failed=list(failed),
        failed_at=dead,
        rejoin=rejoin,
        held=held,
        rejoin_with=older,
    )


def compared_states(
    states: Mapping[ModuleId, list[int]], reference: np.ndarray, outs: Sequence[Outage]
) -> dict[ModuleId, list[int]]:
    """Every module's record as it is compared with ``reference`` (:func:`compared_record`;
    a short outage's skipped transitions: :func:`unshown`)."""
    long = {o.module: o for o in outs if o.long}
    short = {o.module for o in outs if not o.long}
    out = {}
    for m, seq in states.items():
        ref = reference[:, m.leg, m.module].tolist()
        out[m] = compared_record(seq, long[m], ref) if m in long else seq
        if m in short:
            out[m] = unshown(out[m], ref)
    return out


def unshown(seq: list[int], reference: list[int]) -> list[int]:
    """A short outage of an NN module: it relays S^(t+1) before it shows it, so a power-off
    between its downstream's TOOK and its first pulse of S^(t+1) leaves that state taken by its
    neighbours (nobody went on without it) but never shown; it rejoins at the next. The
    reference stands in for that transition (``OFF_STATE`` in the record), as for a long one."""
    return [reference[t] if v == OFF_STATE and t < len(reference) else v for t, v in enumerate(seq)]


def compared_record(seq: list[int], outage: Outage, reference: list[int]) -> list[int]:
    """The reset module's own record as it is compared: from T + 1 to the transition before its
    record restarts it showed states no neighbour received, then nothing (limp); there the
    reference (its held state) stands in for it. From T itself when it never showed S^T: an NN
    module relays S^T before it shows it, so a power-off between its downstream's TOOK and its
    first pulse of S^T leaves S^T held downstream and nothing shown."""
    if not outage.long or outage.failed_at is None:
        return seq
    stop = len(reference) if outage.rejoined_at is None else outage.rejoined_at
    out = list(seq) + [OFF_STATE] * max(0, stop - len(seq))
    first = outage.failed_at + (
        0 <= outage.failed_at < len(out) and out[outage.failed_at] != OFF_STATE
    )
    for t in range(first, min(stop, len(out), len(reference))):
        out[t] = reference[t]
    return out


def nn_power_up_cut_reference(
    ctrl: Controller,
    transitions: int,
    cuts: Sequence[frozenset[ModuleId] | tuple[ModuleId, ModuleId]],
    failed_at: Mapping[ModuleId, int] | None = None,
) -> np.ndarray | None:
    """NN: R^0..R^T with chain wires A - B (B = A + 1) cut from power-up (protocol/link.md
    §4.6, cut): A marks B dead and feeds B + 1 on the bypass with B's R^0, so every module but
    B follows ``--fail B``; B hears nobody upstream and paces on the R^0 of 0..A, so B follows
    its leg's upstream failed (``--fail`` of 0..A). A cut bypass changes nothing. None when a
    leg has two cut chain wires (no documented behaviour). ``failed_at``: modules failing
    during the run besides (a chain wire cut in a running robot, :func:`nn_cut_failures`)."""
    chain = {}
    for pair in cuts:
        up, down = sorted(pair)
        if up.leg != down.leg or down.module - up.module != 1:
            continue  # a bypass: it carries states only while its chain wire is dead
        if up.leg in chain:
            return None
        chain[up.leg] = down
    dies = dict(failed_at or {})
    out = ctrl.states(transitions, failed=list(chain.values()), failed_at=dies).astype(np.int64)
    for down in chain.values():
        upstream = [ModuleId(down.leg, j) for j in range(down.module)]
        later = {m: t for m, t in dies.items() if m not in upstream}
        alone = ctrl.states(transitions, failed=upstream, failed_at=later)
        out[:, down.leg, down.module] = alone[:, down.leg, down.module]
    return out


def cut_reference(
    ctrl: Controller, transitions: int, cuts: Sequence[tuple[ModuleId, ModuleId]]
) -> np.ndarray:
    """CA: R^0..R^T when each end of a cut wire reads the other end's R^0 for ever (it never
    heard it: dead from power-up for that end only), every other neighbour as healthy: a
    per-link view of the ends whose rule reads the other."""
    held = [(r, s, 0) for a, b in cuts for r, s in ((a, b), (b, a))]
    return held_link_reference(ctrl, transitions, held)


def held_link_reference(
    ctrl: Controller, transitions: int, held: Sequence[tuple[ModuleId, ModuleId, int]]
) -> np.ndarray:
    """CA: R^0..R^T when each reader of ``held`` (reader, source, W) reads, from the rule step
    of transition W on (the one computing R^(W+1)), the source's state of W - 1 (W = 0: R^0)
    instead of its own: the state it last got before the wire went silent for it (it waited in
    W, then held the source dead). Every other neighbour reads as healthy. Readers whose rule
    does not read the source are left out."""
    from bstool.controllers.reference import ca_neighbours
    from bstool.controllers.sequences import ca_sequences

    n, m = ctrl.legs, ctrl.modules
    reads = [(r, s, w) for r, s, w in held
             if (s.leg, s.module) in ca_neighbours(ctrl.model, n, m, r.leg, r.module)]  # fmt: skip
    rules = ctrl.rules()
    rules = rules[None] if ctrl.model == "ca2ddiff" else rules
    out = np.empty((transitions + 1, n, m), dtype=np.int64)
    out[0] = ctrl.initial_states
    for t in range(transitions):
        views = {((r.leg, r.module), (s.leg, s.module)): int(out[max(w - 1, 0), s.leg, s.module])
                 for r, s, w in reads if t >= w}  # fmt: skip
        step = ca_sequences(ctrl.model, out[t][None], rules, 1, (), views)
        out[t + 1] = step[0, 1].reshape(n, m)
    return out


def timed_cut_holds(
    twin: RobotTwin, cuts_at: Mapping[frozenset[ModuleId], float]
) -> list[tuple[ModuleId, ModuleId, int]]:
    """CA: for wires cut (or gone one-way) at S seconds in a running robot, (reader, source,
    W) of each end: W is the transition the reader waited in after S (the one it showed at S
    or the next, whichever lasted longer: :func:`_wait`), read from its record."""
    out = []
    for pair, at_s in cuts_at.items():
        a, b = sorted(pair)
        for reader, source in ((a, b), (b, a)):
            w = _longest_after(twin.records[reader].times_ns, at_s)
            if w is not None:
                out.append((reader, source, w))
    return out


def _longest_after(times_ns: list[int], at_s: float, span: int = 3) -> int | None:
    """The transition, of the one shown at ``at_s`` and the ``span`` - 1 after it, that lasted
    longest after ``at_s``: the reader's wait for the dead-limit (>= 1.5 s) against ordinary
    transitions. Three, not two as for an outage: on a one-way wire the reader may still get
    the state of the transition after the one it showed (its answer, not the request, is lost)."""
    at = at_s * NS
    shown = [i for i, t in enumerate(times_ns) if 0 <= t <= at]
    if not shown:
        return None
    s = shown[-1]

    def lasted(w: int) -> float:
        end = times_ns[w + 1] if w + 1 < len(times_ns) and times_ns[w + 1] >= 0 else math.inf
        return end - max(times_ns[w], at) if w < len(times_ns) else -math.inf

    return max(range(s, s + span), key=lasted)


__all__ = [
    "OFF_STATE",
    "Outage",
    "ca_readers",
    "compared_record",
    "compared_states",
    "cut_reference",
    "held_link_reference",
    "nn_cut_failures",
    "nn_power_up_cut_reference",
    "outage_reference",
    "outages",
    "readers",
    "timed_cut_holds",
    "unshown",
]
