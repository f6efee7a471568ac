"""Everything one module's program needs, decided in Python before any template runs.

A :class:`ModulePlan` is plain data: the templates only print it, the manifest and WIRING.md
describe it, and :mod:`bstool.compile.emulate` runs it at the state level, so the tests can
compare the compiled tables with the reference without a BS2sx.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from bstool.compile import tables, timing
from bstool.compile.calibration import Calibration
from bstool.compile.topology import Link, links, module_links, pin_role, reads
from bstool.controllers import CA_MODELS, Controller
from bstool.errors import BuildError
from bstool.moduleid import ModuleId, all_modules
from bstool.wire import announce
from bstool.wire import link as wire

PORT_NAMES = {
    "prev": "LinkPrev",
    "next": "LinkNext",
    "lead_left": "LinkLeft",
    "lead_right": "LinkRight",
    "bypass_prev": "LinkByPrev",
    "bypass_next": "LinkByNext",
}


@dataclass(frozen=True)
class LocalLink:
    """One link seen from one end, in the module's run order."""

    number: int  # position in the module's run order (label Link<number>)
    link: Link
    peer: ModuleId
    master: bool
    pin: int
    port: str  # PBASIC PIN name
    send: tuple[str, ...]  # PBASIC expressions of the states sent
    store: tuple[str, ...]  # variables that receive the decoded states ("" = check only)
    only_if_dead: int = -1  # NN bypass: needed only while the link with this number is dead

    @property
    def tx_payload(self) -> int:
        return len(self.send)

    @property
    def rx_payload(self) -> int:
        return len(self.store)


@dataclass
class ModulePlan:
    mid: ModuleId
    model: str
    family: str  # "ca" or "nn"
    hash8: str
    r0: int
    pulses: list[int]
    clipped: list[int]
    links: list[LocalLink]
    known: list[tuple[ModuleId, int]]  # nb(i) (CA) / up(i) (NN): whose state, initial value
    known_var: str
    left: str = "state"  # CA: expressions of L and R
    right: str = "state"
    rule_slots: list[bytes] = field(default_factory=list)
    nn_lead: bool = False
    nn_terms: list[int] = field(default_factory=list)  # up() indices with w = 1
    nn_table: list[int] = field(default_factory=list)
    rx_size: int = 1
    serve: wire.ServeConstants = wire.CA  # the serve loop's constants (bstool.wire.link)
    dead_ticks: int = 0  # DeadTicks: silent ticks before a wire is dead (>= the dead-limit)
    hold_frames: int = wire.CA.hold_frames  # HoldFrames: from the period (hold_for_period)
    # CA: the hold clock (protocol/link.md §4.2): each try adds its estimated length besides its
    # pulse (SERIN units); a hold frame is FrameTime units, the same on every module
    master_try_units: int = 0
    listen_try_units: int = 0
    heard_try_units: int = 0
    frame_units: int = 0
    timing: timing.CompileTiming = timing.DEFAULT  # the estimates' timing model

    @property
    def label(self) -> str:
        return self.mid.label

    @property
    def announcement(self) -> str:
        """The start-up line the program sends on DEBUG (bstool.wire.announce)."""
        return announce.line(self.mid, self.hash8)

    @property
    def dirname(self) -> str:
        return self.mid.label

    @property
    def slot_files(self) -> list[str]:
        """Project files: main.bsx, then one per rule slot (slots 1..)."""
        return ["main.bsx"] + [f"rules{s}.bsx" for s in range(1, len(self.rule_slots) + 1)]

    @property
    def rx_names(self) -> list[str]:
        return ["rx"] if self.rx_size == 1 else [f"rx({i})" for i in range(self.rx_size)]

    @property
    def sum_expr(self) -> str:
        return " + ".join(f"{self.known_var}({a})" for a in self.nn_terms) or "0"


def _known_index(known: list[tuple[ModuleId, int]], mid: ModuleId) -> int:
    return [k for k, _ in known].index(mid)


def build_plans(
    ctrl: Controller,
    calibration: Calibration,
    period_s: float,
    hash8: str,
    only: list[ModuleId] | None = None,
    *,
    model: timing.CompileTiming = timing.DEFAULT,
) -> list[ModulePlan]:
    """One plan per module (all, or ``only``), in canonical order, with HoldFrames for the
    period ``period_s`` (the whole robot's, whatever ``only``) by the timing ``model``."""
    n, m = ctrl.legs, ctrl.modules
    r0 = ctrl.states(0)[0]
    all_links = links(ctrl.model, n, m)
    wanted = set(only) if only else None
    every = [
        _plan(ctrl, mid, all_links, r0, calibration, hash8, model) for mid in all_modules(n, m)
    ]
    if every and every[0].family == "ca":
        _set_hold_clock(every)
    set_hold_frames(every, hold_for_period(every, period_s * 1000))
    return [p for p in every if wanted is None or p.mid in wanted]


def _set_hold_clock(plans: list[ModulePlan]) -> None:
    """CA: the hold clock's estimates (SERIN units), the same in every module of the robot: a
    frame, and a master's try and a listen besides their pulses."""
    t, k = plans[0].timing, plans[0].serve
    unit = t.serin_unit_ms
    frame = round(_ca_frame_ms(plans) / unit)
    pulse = _pulse_ms(plans[0])
    ask = round(t.ca_ask_ms(k, pulse) / unit)
    listen = round(t.ca_listen_ms(k) / unit)
    heard = round(t.ca_heard_ms(k, pulse) / unit)
    for p in plans:
        p.frame_units, p.master_try_units, p.listen_try_units = frame, ask, listen
        p.heard_try_units = heard


def _plan(
    ctrl: Controller,
    mid: ModuleId,
    all_links: list[Link],
    r0: object,
    calibration: Calibration,
    hash8: str,
    model: timing.CompileTiming,
) -> ModulePlan:
    import numpy as np

    grid = np.asarray(r0)
    servo = calibration.servo(mid)
    pulses = servo.pulses(ctrl.k)
    mine = module_links(all_links, mid)
    pins = [lk.pin(mid) for lk in mine]
    if len(set(pins)) != len(pins):  # pragma: no cover - topology invariant
        raise BuildError(f"{mid.label}: two links on one pin {pins}")
    family = "ca" if ctrl.model in CA_MODELS else "nn"
    known: list[tuple[ModuleId, int]] = []
    plan = ModulePlan(
        mid=mid,
        model=ctrl.model,
        family=family,
        hash8=hash8,
        r0=int(grid[mid.leg, mid.module]),
        pulses=pulses,
        clipped=servo.clipped(ctrl.k),
        links=[],
        known=known,
        known_var="nb" if family == "ca" else "up",
        timing=model,
    )
    if family == "ca":
        for lk in mine:
            peer = lk.peer(mid)
            known.append((peer, int(grid[peer.leg, peer.module])))
        left, right = reads(ctrl.model, ctrl.legs, ctrl.modules, mid)
        plan.left = "state" if left == mid else f"nb({_known_index(known, left)})"
        plan.right = "state" if right == mid else f"nb({_known_index(known, right)})"
        rule = tables.module_rule(ctrl, mid)
        plan.rule_slots = [tables.rule_slot_bytes(rule, s) for s in range(1, tables.RULE_SLOTS + 1)]
    else:
        for a in range(mid.module):
            up = ModuleId(mid.leg, a)
            known.append((up, int(grid[up.leg, up.module])))
        plan.nn_lead = mid.module == 0
        if not plan.nn_lead:
            weights = tables.nn_weights_in(ctrl, mid)
            plan.nn_terms = [a for a, w in enumerate(weights) if w]
            plan.nn_table = tables.nn_table(ctrl, mid)
    rx_size = 1
    for number, lk in enumerate(mine):
        master = lk.master == mid
        peer = lk.peer(mid)
        if family == "ca":
            send: tuple[str, ...] = ("state",)
            store: tuple[str, ...] = (f"nb({_known_index(known, peer)})",)
        elif master:  # upstream: the t+1 states of modules 0..j
            send = (*(f"up({a})" for a in range(mid.module)), "state")
            store = ()  # the reply is a bare header: an acknowledgement
        else:  # the t+1 states of modules 0..peer (a bypass: the dead j-1's held state stays)
            send = ()
            store = tuple(f"up({a})" for a in range(peer.module + 1))
        guard = -1
        if lk.bypass:  # the chain wire to the module this one bypasses
            between = ModuleId(mid.leg, (lk.master.module + lk.slave.module) // 2)
            guard = next(i for i, other in enumerate(mine) if other.peer(mid) == between)
        rx_size = max(rx_size, len(store))
        plan.links.append(
            LocalLink(
                number=number,
                link=lk,
                peer=peer,
                master=master,
                pin=lk.pin(mid),
                port=PORT_NAMES[pin_role(ctrl.model, ctrl.legs, ctrl.modules, mid, peer)],
                send=send,
                store=store,
                only_if_dead=guard,
            )
        )
    longest = max((max(len(ll.send), len(ll.store)) for ll in plan.links), default=0)
    if family == "nn" and longest > wire.MAX_PACKED_STATES:
        raise BuildError(
            f"{mid.label}: a states frame of {longest} states is longer than the "
            f"{wire.MAX_PACKED_STATES} its check protects (protocol/link.md §4.6)",
            hint=f"NN legs of more than {wire.MAX_PACKED_STATES + 1} modules are not supported",
        )
    plan.rx_size = rx_size
    plan.serve = wire.serve_constants(family == "nn")
    plan.dead_ticks = wire.nn_dead_ticks() if family == "nn" else wire.ca_dead_ticks()
    return plan


def _pulse_ms(plan: ModulePlan) -> float:
    return plan.pulses[len(plan.pulses) // 2] * plan.timing.pulsout_unit_ms


def _tries(plan: ModulePlan, *, jitter: float) -> list[float]:
    """Per wire, the length of the try that wire usually costs in a round (timing model): a
    master's answered try, a slave's listen (a master sends to it only until it has the reply
    and then every 4th round, so most of a slave's tries listen out)."""
    k, nn, t = plan.serve, plan.family == "nn", plan.timing
    pulse = _pulse_ms(plan)
    out = []
    for ll in plan.links:
        if ll.master and not (nn and ll.link.bypass):
            out.append(t.master_try_ms(pulse, ll.tx_payload, ll.rx_payload, k, nn=nn))
        elif not ll.master:
            every = k.keepalive_rounds if ll.link.bypass else 1
            out.append(t.listen_ms(pulse, k, jitter=jitter) / every)
    return out


def _longest_gap_ms(plan: ModulePlan) -> float:
    k, nn, t = plan.serve, plan.family == "nn", plan.timing
    gaps = [t.listen_ms(0.0, k, jitter=k.jitter_units)]
    if not nn:
        gaps.append(t.transition_end_ms() + gaps[0])
    elif plan.nn_lead:
        gaps.append(timing.NN_IDLE_PAUSE_MS + t.statements(timing.NN_LEAD_GAP_STATEMENTS))
    for ll in plan.links:
        if ll.master:
            gaps.append(t.master_gap_ms(ll.tx_payload, ll.rx_payload, k, nn=nn))
            if not nn:  # line noise: the REP's payload lost, PayloadWait in the gap
                gaps.append(t.lost_payload_gap_ms(ll.tx_payload, k))
        else:
            longest = max(plan.pulses) * t.pulsout_unit_ms  # the master's pulse, about ours
            gaps.append(t.slave_receive_gap_ms(ll.rx_payload, k, nn=nn, master_pulse_ms=longest))
    return max(gaps)


MEAN_JITTER = 3.5


def _ca_frame_ms(plans: list[ModulePlan]) -> float:
    """CA: one hold frame: a listen try with the robot's middle pulse (the hold clock counts
    every try's estimated length, so a frame is a length of time, not a try)."""
    return plans[0].timing.ca_listen_ms(plans[0].serve) + _pulse_ms(plans[0])


def _ca_exchange_ms(plans: list[ModulePlan]) -> float:
    """CA: a transition besides its hold (timing.CA_EXCHANGE_ROUNDS): the wait of the module
    that switches last for its next Due test and the switch itself."""
    busiest = max(sum(_tries(p, jitter=MEAN_JITTER)) for p in plans)
    return timing.CA_EXCHANGE_ROUNDS * busiest


def _nn_meeting_ms(plans: list[ModulePlan], p: ModulePlan, ll: LocalLink) -> float:
    """NN: a master's REQ meeting a listen on its slave: about (slave round / listen) tries,
    each a master round."""
    by = {q.mid: q for q in plans}
    listen = p.timing.listen_ms(0.0, p.serve, jitter=MEAN_JITTER)
    peer = sum(_tries(by[ll.peer], jitter=MEAN_JITTER)) if ll.peer in by else listen
    return peer / listen * sum(_tries(p, jitter=MEAN_JITTER))


def _nn_relay_ms(plans: list[ModulePlan]) -> float:
    """NN: the relay's period at the busiest hop: NN_MEETINGS meetings and a take."""
    worst = 0.0
    for p in plans:
        for ll in p.links:
            if ll.master and not ll.link.bypass:
                take = p.timing.take_ms(_pulse_ms(p), ll.tx_payload, p.serve)
                worst = max(worst, timing.NN_MEETINGS * _nn_meeting_ms(plans, p, ll) + take)
    return worst


def _nn_lead_frame_ms(plans: list[ModulePlan], lead: ModulePlan) -> float:
    """NN: the lead's mean servo frame while it holds a state module 1 shows: a keep-alive
    poll every keepalive_rounds rounds (answered when module 1 listens: its listen's share of
    its round), idle frames between."""
    k, t, pulse = lead.serve, lead.timing, _pulse_ms(lead)
    chain = next(ll for ll in lead.links if ll.master and not ll.link.bypass)
    by = {q.mid: q for q in plans}
    listen = t.listen_ms(pulse, k, jitter=MEAN_JITTER)
    peer = by.get(chain.peer)
    share = listen / sum(_tries(peer, jitter=MEAN_JITTER)) if peer is not None else 1.0
    poll = share * t.master_try_ms(pulse, 1, 0, k, nn=True) + (1 - share) * t.miss_ms(pulse, k)
    every = k.keepalive_rounds
    return ((every - 1) * t.idle_ms(pulse) + poll) / every


def _nn_hold_fixed_ms(plans: list[ModulePlan], lead: ModulePlan) -> float:
    """NN: a lead's transition besides its hold: the take by module 1 after it advances."""
    chain = next(ll for ll in lead.links if ll.master and not ll.link.bypass)
    return _nn_meeting_ms(plans, lead, chain) + lead.timing.take_ms(
        _pulse_ms(lead), chain.tx_payload, lead.serve
    )


def _nn_lead(plans: list[ModulePlan]) -> ModulePlan | None:
    return next((p for p in plans if p.nn_lead and p.links), None)


def min_hold_frames(plans: list[ModulePlan]) -> int:
    """The protocol's floor of HoldFrames: NN the lead's floor (bstool.wire.link NN); CA
    keepalive_rounds frames (a policy: a transition also waits for every neighbour state, so no
    handshake needs the hold; a servo needs time to move; a 2-D robot keeps in step only from
    about 25 frames, protocol/link.md §4.2)."""
    if plans[0].family == "nn":
        return wire.NN.hold_frames
    return wire.CA.keepalive_rounds


def hold_for_period(plans: list[ModulePlan], period_ms_wanted: float) -> int:
    """HoldFrames that make the unperturbed period about ``period_ms_wanted`` at the timing
    model's speed (never below :func:`min_hold_frames`)."""
    floor = min_hold_frames(plans)
    if plans[0].family == "ca":
        per, fixed = _ca_frame_ms(plans) * timing.CA_FRAME_RATIO, _ca_exchange_ms(plans)
    else:
        lead = _nn_lead(plans)
        if lead is None:
            return floor
        per, fixed = _nn_lead_frame_ms(plans, lead), _nn_hold_fixed_ms(plans, lead)
    if per <= 0:  # a robot of one module: no tries, nothing to pace
        return floor
    return max(floor, round((period_ms_wanted - fixed) / per))


def set_hold_frames(plans: list[ModulePlan], hold: int) -> None:
    for p in plans:
        p.hold_frames = hold


def period_ms(plans: list[ModulePlan]) -> float:
    """The robot's nominal period (timing model, for reporting and for HoldFrames). CA: every
    module shows a state for HoldFrames tries, the slowest module's tries set the pace. NN: the
    longer of the relay (NN_MEETINGS meetings of a master's try with a listen per transition at
    the busiest hop, and a take) and the lead's hold (HoldFrames lead frames and module 1's
    take)."""
    if not plans:
        return 0.0
    hold = plans[0].hold_frames
    if plans[0].family == "ca":
        return hold * _ca_frame_ms(plans) * timing.CA_FRAME_RATIO + _ca_exchange_ms(plans)
    lead = _nn_lead(plans)
    held = 0.0
    if lead is not None:
        held = hold * _nn_lead_frame_ms(plans, lead) + _nn_hold_fixed_ms(plans, lead)
    return max(_nn_relay_ms(plans), held)


def floor_period_ms(plans: list[ModulePlan]) -> float:
    """The estimated period at the floor of HoldFrames: what the handshakes can do."""
    saved = plans[0].hold_frames
    set_hold_frames(plans, min_hold_frames(plans))
    try:
        return period_ms(plans)
    finally:
        set_hold_frames(plans, saved)


def estimates(plan: ModulePlan, period: float) -> dict[str, float]:
    """The timing model's estimates for one module, in seconds: the robot's nominal period
    (``period``, ms, :func:`period_ms`), the first transition after a common power-up (the join:
    a few tries, then R^0 for a period) and the longest gap between two servo pulses."""
    join = 2 * sum(_tries(plan, jitter=plan.serve.jitter_units))
    return {
        "nominal_transition_s": round(period / 1000, 4),
        "first_transition_s": round((join + period) / 1000, 4),
        "longest_servo_gap_s": round(_longest_gap_ms(plan) / 1000, 4),
    }
