"""Everything one module's program needs, decided in Python before any template runs.

A :class:`ModulePlan` is plain data: the templates only print it, the manifest and WIRING.md
describe it, and :mod:`bstool.compile.emulate` runs it at the state level, so the tests can
compare the compiled tables with the reference without a BS2sx.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from bstool.compile import tables, timing
from bstool.compile.calibration import Calibration
from bstool.compile.topology import Link, links, module_links, pin_role, reads
from bstool.controllers import CA_MODELS, Controller
from bstool.errors import BuildError
from bstool.moduleid import ModuleId, all_modules
from bstool.wire import announce
from bstool.wire.link import REPLY_BASE_UNITS

PORT_NAMES = {
    "prev": "LinkPrev",
    "next": "LinkNext",
    "lead_left": "LinkLeft",
    "lead_right": "LinkRight",
    "bypass_prev": "LinkByPrev",
    "bypass_next": "LinkByNext",
}
MAX_PAYLOAD = 15  # receive buffer bytes (RAM)


@dataclass(frozen=True)
class LocalLink:
    """One link seen from one end, in the module's run order."""

    number: int  # position in the module's run order (label Link<number>)
    link: Link
    peer: ModuleId
    master: bool
    pin: int
    port: str  # PBASIC PIN name
    deadline: int  # ms from the start of the exchange: give up (keep the last known state)
    first_deadline: int  # the same in the roll call; then the neighbour counts as dead
    iter_ms: int  # what one unanswered wait iteration adds to the clock
    send: tuple[str, ...]  # PBASIC expressions of the states sent
    store: tuple[str, ...]  # variables that receive the decoded states ("" = check only)
    wait_units: int  # pulse + SERIN timeout (0.4 ms units): ReplyBase or SlaveBase
    only_if_dead: int = -1  # NN bypass: run only while the link with this number is dead
    near_deadline: int = 0  # NN bypass master: the deadline while its chain wire is dead (0: none)
    reports_dead: int = -1  # NN chain slave: its reply says whether this link's peer is dead
    next_dead: int = -1  # NN chain master: the bypass link a reply of $F8 + t marks dead
    ok_ms: int = 0  # what a successful try adds (the whole try, as it ends the exchange)
    recover_ms: int = 0  # slave: what catching only the tail of a request adds

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
    hold_pause: int
    hold_step: int
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
    hold_ms: int = 0  # clock target of a transition (the period, ms from the exchange start)
    exch_ms: int = 0  # exchange allowance: the clock is capped at this when the exchange ends
    free_ms: int = 0  # when this module's exchange ends without faults (clock after roll call)
    roll_ms: int = 0
    pad_base: int = 0  # servo + pad pulse of a holding frame (PULSOUT units)

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
) -> list[ModulePlan]:
    """One plan per module (all, or ``only``), in canonical order."""
    n, m = ctrl.legs, ctrl.modules
    r0 = ctrl.states(0)[0]
    all_links = links(ctrl.model, n, m)
    wanted = set(only) if only else None
    every = [
        _plan(ctrl, mid, all_links, r0, calibration, period_s, hash8) for mid in all_modules(n, m)
    ]
    exchange = exchange_ms(every)
    roll = timing.roll_ms(max((lk.colour for lk in all_links), default=0), exchange)
    for plan in every:
        plan.hold_ms = round(period_s * 1000)
        plan.exch_ms = timing.allowance_ms(exchange, plan.hold_ms, plan.hold_step)
        plan.free_ms = min(plan.exch_ms, round(_own_exchange_ms(plan, every)))
        plan.roll_ms = roll
        if plan.family == "nn":
            plan.links = [_near(plan, ll) for ll in plan.links]
    return [p for p in every if wanted is None or p.mid in wanted]


def _near(plan: ModulePlan, ll: LocalLink) -> LocalLink:
    """The deadline of an NN bypass master while the chain wire it replaces is dead.

    The bypass is then this module's only wire downstream; if its peer falls silent too (two
    dead neighbours in a row) this module must still be back, in the next transition, before
    its upstream neighbour gives up on it — however early that neighbour is (by up to the
    exchange allowance ExchMs, or by the lateness a single death downstream once left this module
    with). The full bypass deadline (an extra window for the meeting in the transition
    a module first goes silent) would make it too late: its upstream gave up, the two fell a
    transition apart and marked each other dead (issue 16). The lead has no upstream."""
    if not (ll.master and ll.link.bypass):
        return ll
    ups = [u.deadline for u in plan.links if not u.master and not u.link.bypass]
    if not ups:
        return ll
    # how early the upstream neighbour may be: within the allowance, or as late as this module
    # once was after a single death downstream (waiting until its longest deadline; the
    # upstream then met it past LateMs and kept one holding frame, so it keeps that lead)
    late = max(d.deadline for d in plan.links if d.master) + plan.hold_step - plan.hold_ms
    early = max(plan.exch_ms, late)
    back_by = ups[0] + plan.hold_ms - plan.hold_step - early - timing.NEAR_SAFETY_MS
    near = min(ll.deadline, back_by)
    return replace(ll, near_deadline=near) if near < ll.deadline else ll


def _gap_ms(plan: ModulePlan, ll: LocalLink) -> float:
    """The longest time between two servo pulses on this wire."""
    pulse_max_ms = max(plan.pulses) * timing.PULSOUT_UNIT_MS
    if ll.master:
        return timing.master_gap_ms(pulse_max_ms, ll.tx_payload, ll.rx_payload)
    return timing.slave_gap_ms(pulse_max_ms, ll.rx_payload, ll.tx_payload)


def _iteration_ms(plan: ModulePlan, ll: LocalLink) -> float:
    """A fault-free exchange on this wire: a master's answered try; a slave's wait, reply and
    linger."""
    pulse_max_ms = max(plan.pulses) * timing.PULSOUT_UNIT_MS
    if ll.master:
        return timing.master_gap_ms(pulse_max_ms, ll.tx_payload, ll.rx_payload)
    return timing.slave_exchange_ms(pulse_max_ms, ll.rx_payload, ll.tx_payload)


def _linger_ms(plan: ModulePlan) -> float:
    """NN: the linger after receiving on the chain wire, before computing and sending on."""
    return sum(timing.linger_ms() for ll in plan.links if not ll.master and not ll.link.bypass)


def _compute_ms(plan: ModulePlan) -> float:
    return (2 * timing.RUN_MS + 6 * timing.STMT_MS) if plan.family == "ca" else 1.0


def _own_exchange_ms(plan: ModulePlan, plans: list[ModulePlan]) -> float:
    """When this module's fault-free exchange ends: its own wires, one try each; NN: after the
    relay from the lead has reached it."""
    own = sum(_iteration_ms(plan, ll) for ll in plan.links if not ll.link.bypass)
    if plan.family == "nn":
        upstream = [
            p for p in plans if p.mid.leg == plan.mid.leg and p.mid.module < plan.mid.module
        ]
        own = (
            sum(
                _iteration_ms(p, ll) + _compute_ms(p) + _linger_ms(p)
                for p in upstream
                for ll in p.links
                if ll.master and not ll.link.bypass and ll.peer.module == p.mid.module + 1
            )
            + sum(_iteration_ms(plan, ll) for ll in plan.links if ll.master and not ll.link.bypass)
            + _linger_ms(plan)
        )
    return own + _compute_ms(plan)


def exchange_ms(plans: list[ModulePlan]) -> float:
    """Fault-free exchange phase of the robot: the longest module's wires, one iteration each
    (NN: the whole relay down the leg, since the last module waits for every hop)."""
    longest = 0.0
    for plan in plans:
        used = [ll for ll in plan.links if not ll.link.bypass]  # bypasses idle without failures
        own = sum(_iteration_ms(plan, ll) for ll in used) + _compute_ms(plan)
        longest = max(longest, own)
    if plans and plans[0].family == "nn":
        relay = [
            sum(
                _iteration_ms(p, ll) + _compute_ms(p)
                for ll in p.links
                if ll.master and not ll.link.bypass
            )
            + _linger_ms(p)
            for p in plans
        ]
        longest = max(longest, sum(relay) / max(1, len({p.mid.leg for p in plans})))
    return longest


def _plan(
    ctrl: Controller,
    mid: ModuleId,
    all_links: list[Link],
    r0: object,
    calibration: Calibration,
    period_s: float,
    hash8: str,
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
        hold_pause=timing.hold_pause_ms(max(pulses)),
        hold_step=0,
        links=[],
        known=known,
        known_var="nb" if family == "ca" else "up",
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
        else:  # the t+1 states of modules 0..peer (a bypass leaves the dead j-1 at R^0)
            send = ()
            store = tuple(f"up({a})" for a in range(peer.module + 1))
        guard = reports = flags = -1
        if lk.bypass:  # the chain wire to the module this one bypasses
            between = ModuleId(mid.leg, (lk.master.module + lk.slave.module) // 2)
            guard = next(i for i, other in enumerate(mine) if other.peer(mid) == between)
        elif family == "nn":  # chain wire: the next module's dead mark travels upstream
            beyond = ModuleId(mid.leg, peer.module + 1 if master else mid.module + 1)
            for i, other in enumerate(mine):
                if master and other.bypass and other.peer(mid) == beyond:
                    flags = i  # the bypass to the module after the peer
                if not master and not other.bypass and other.peer(mid) == beyond:
                    reports = i  # this module's own chain wire to its next module
        rx_size = max(rx_size, len(store))
        pulse_mid_ms = pulses[ctrl.k // 2] * timing.PULSOUT_UNIT_MS
        if master:
            units = REPLY_BASE_UNITS
            miss = timing.master_miss_ms(len(send))
            ok = timing.master_ok_ms(pulse_mid_ms, len(send), len(store))
        else:
            units = timing.SLAVE_BASE_UNITS
            miss = timing.slave_miss_ms()
            ok = timing.slave_ok_ms(pulse_mid_ms, len(store), len(send))
        plan.links.append(
            LocalLink(
                number=number,
                link=lk,
                peer=peer,
                master=master,
                pin=lk.pin(mid),
                port=PORT_NAMES[pin_role(ctrl.model, ctrl.legs, ctrl.modules, mid, peer)],
                deadline=timing.DEADLINE_BASE_MS
                + (lk.colour + 1 + timing.BYPASS_EXTRA_WINDOWS * lk.bypass) * timing.WINDOW_MS,
                first_deadline=timing.FIRST_BASE_MS + (lk.colour + 1) * timing.FIRST_WINDOW_MS,
                iter_ms=max(1, round(miss)),
                ok_ms=max(1, round(ok)),
                recover_ms=0 if master else round(timing.recover_ms(pulse_mid_ms)),
                send=send,
                store=store,
                wait_units=units,
                only_if_dead=guard,
                reports_dead=reports,
                next_dead=flags,
            )
        )
    if rx_size > MAX_PAYLOAD:
        raise BuildError(
            f"{mid.label}: a frame of {rx_size} states does not fit the receive buffer",
            hint=f"NN legs of more than {MAX_PAYLOAD + 1} modules are not supported",
        )
    plan.rx_size = rx_size
    plan.hold_step = round(timing.FRAME_MS)
    plan.pad_base = timing.pad_base(plan.hold_pause)
    return plan


def estimates(plan: ModulePlan, exchange: float) -> dict[str, float]:
    """Transition times and the longest servo-pulse gap, in seconds (timing model).

    ``exchange`` is the robot's fault-free exchange phase in ms (:func:`exchange_ms`).
    """
    pulse_max_ms = max(plan.pulses) * timing.PULSOUT_UNIT_MS
    hold = timing.hold_frame_ms(pulse_max_ms, plan.hold_pause)
    # the last holding (or roll-call) frame runs on through the lookup to the next PULSOUT
    iters = [hold + _compute_ms(plan) + timing.AFTER_MS]
    iters += [_gap_ms(plan, ll) for ll in plan.links]
    gap = max(iters)
    last_deadline = max((ll.deadline for ll in plan.links), default=0)
    silent = last_deadline + gap + _compute_ms(plan)
    # a transition lasts hold_ms on the module's clock unless the exchange overran exch_ms; an
    # exchange past LATE_MS (a silent neighbour's wait) keeps one holding frame
    rest = plan.hold_step if silent >= timing.LATE_MS else plan.hold_ms - plan.exch_ms
    return {
        "nominal_transition_s": round(plan.hold_ms / 1000, 4),
        "fault_free_exchange_s": round(exchange / 1000, 4),
        "worst_case_transition_s": round(max(plan.hold_ms, silent + rest) / 1000, 4),
        # power-up: one period showing R^0, then the roll call; R^1 shows when it ends
        "first_transition_s": round((plan.hold_ms + plan.roll_ms) / 1000, 4),
        "longest_servo_gap_s": round(gap / 1000, 4),
    }
