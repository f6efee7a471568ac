"""Timing model of a module program on a BS2sx: the waits the programs use, the clock they keep,
and the manifest's estimates (worst-case transition, longest gap between servo pulses).

Model (docs/compile.md): every PBASIC statement costs :data:`STMT_MS` (a BS2sx runs about
10,000 instructions/s, bs2sx.md §1) plus its own time: PULSOUT its pulse, PAUSE its argument,
SEROUT/SERIN 10 bit times per byte, SERIN its timeout when nothing comes, RUN :data:`RUN_MS`.

The programs have no clock; they add the estimated length of every loop they run to a ``clock``
variable (ms). Wait loops subtract the servo pulse from their SERIN timeout (``pulse / 500`` is
the pulse in 0.4 ms units), so every wait iteration lasts about the same whatever the state:
the estimate then errs by about the same factor on every module, which keeps the staggered
give-up deadlines in order.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from bstool.timingfile import DEFAULT as DEFAULT_MODEL
from bstool.timingfile import TimingModel
from bstool.wire.link import (
    LINGER_LISTENS,
    LINGER_UNITS,
    RECOVER_UNITS,
    REPLY_BASE_UNITS,
    byte_ms,
)

STMT_MS = 0.1
RUN_MS = 0.3
SERIN_UNIT_MS = 0.4  # BS2sx SERIN timeout unit
PULSOUT_UNIT_MS = 0.0008
PULSE_PER_SERIN_UNIT = 500  # 0.4 ms / 0.8 us: ``pulse / 500`` is the pulse in SERIN units
FRAME_MS = 20.0  # nominal servo frame while holding a state
AFTER_MS = 2.0
"""Upper bound of the statements between the end of an exchange and the next PULSOUT (the next
link starts with one; the last one goes through the rule slot and back, two RUNs)."""
HOLD_STATEMENTS = 6  # PULSOUT Servo, PULSOUT Pad, IF, PAUSE, clock = clock + HoldStep, GOTO
HOLD_STMT_MS = 0.102
"""Mean time of a holding-loop statement: these are short statements (calibrated on the twin's
interpreter model, 20 us + 2 us per token bit; STMT_MS is the general upper estimate)."""
PAD_MIN_MS = 0.2  # the shortest pad pulse (the longest servo pulse still gets one)
PAD_PIN = 13
"""An unconnected pin: its PULSOUT is a delay of 0.8 us resolution (PAUSE has 1 ms)."""

SLAVE_BASE_UNITS = 15
"""A slave's listening time plus its pulse, in 0.4 ms units (6 ms): SERIN timeout
``SlaveBase - pulse / 500`` is 3.8-5.2 ms, longer than one byte (2.08 ms), and a frame (>= 2
bytes) is longer than a pulse, so a slave in its wait loop always receives at least the tail of
a request. If it got only the tail, it pulses once and listens for ``Recover``
(:data:`link.RECOVER_UNITS`), which starts before and ends after the master's next try (a master
leaves ``ReplyBase`` between its tries, more than the slave's listen + pulse): an exchange needs
at most two tries, and retries cannot lock step with the slave's pulses."""
SLAVE_STATEMENTS = 13  # the miss path of a slave try, in STMT_MS (its SERIN/IF are long)
LINGER_STATEMENTS = 2
"""Each listen of a silent linger besides its SERIN: its timeout's jump and IF hdr."""
MISS_STATEMENTS = 4
"""A master's statements from a failed reply (timeout or check) to its next request: clock, IF,
PULSOUT, SEROUT."""
MASTER_STATEMENTS = 12  # the miss path of a master try (calibrated on the twin: 12.9-13.0 ms)
SLAVE_TURNAROUND_MS = 4.0  # request end -> reply start: the slave's checks and one pulse

MUTE_STATEMENTS = 1
"""A successful exchange clears the wire's silent mark (``mute``, protocol/link.md §5)."""

DEADLINE_BASE_MS = 300
"""Every give-up deadline starts with this: more than neighbours drift apart in normal running
(a 2-D CA lead exchanges on 4 wires while its leg modules use 2, so they wait for it)."""
WINDOW_MS = 100
"""Each colour adds this to the deadline, so a module that gave up on a silent neighbour still
reaches its later wires before those neighbours give up on it (with room for the clock
estimate being ~10 % off over the whole wait). Not more: a module that waited for a neighbour
that died after the roll call runs late by about its deadline minus the period in the next
transition, and its neighbours on wires up to 3 colours lower (2-D CA leads) must still meet
it before their own deadlines (150 ms missed them; protocol/link.md §5)."""
LATE_MS = DEADLINE_BASE_MS + WINDOW_MS
"""An exchange that ends this late on the clock (the first give-up deadline) waited for a silent
neighbour, directly or behind a neighbour that did: its clock is then capped one holding frame
short of the period instead of at the allowance ExchMs, so it is only as late as the wait made
it; capping at ExchMs would add a whole hold and leave it later than the silent neighbour's own
neighbours (protocol/link.md §5)."""
BYPASS_EXTRA_WINDOWS = 1
"""An NN bypass j-1 -> j+1 waits one window longer than its colour says: in the transition in
which module j first goes silent, j+1 reaches the bypass only at its chain wire's deadline
(one window after j-1 did), and the two must still meet there with the slave's clock running
a few % slow (one window left them about 30 ms)."""
NEAR_SAFETY_MS = 50
"""An NN bypass that replaces a dead chain wire gives up this much before its module would be
too late for its upstream neighbour's deadline in the next transition (plan._near): room for the
clock estimate and a retry or two."""
FIRST_BASE_MS = 1000
"""Deadline base of the roll call (first exchange after power-up): modules switched on within
about a second of each other still find each other."""
FIRST_WINDOW_MS = 300
"""Per-colour step of the roll-call deadlines (longer waits, so a wider margin)."""


def hold_pause_ms(max_units: int) -> int:
    """PAUSE of the holding loop: what is left of :data:`FRAME_MS` after the statements and the
    longest servo pulse plus a minimal pad pulse."""
    spare = FRAME_MS - HOLD_STATEMENTS * HOLD_STMT_MS - max_units * PULSOUT_UNIT_MS - PAD_MIN_MS
    return max(1, int(spare))


def pad_base(pause_ms: int) -> int:
    """Servo + pad pulse (PULSOUT units) of every holding frame: the frame is then exactly
    :data:`FRAME_MS` (timing model) in every state."""
    return round((FRAME_MS - pause_ms - HOLD_STATEMENTS * HOLD_STMT_MS) / PULSOUT_UNIT_MS)


def hold_frame_ms(pulse_ms: float, pause_ms: int) -> float:
    """One holding frame: with the pad pulse it does not depend on the servo pulse."""
    del pulse_ms
    return FRAME_MS


ALLOWANCE_FACTOR = 1.25
ALLOWANCE_EXTRA_MS = 20
"""The exchange allowance is the fault-free exchange estimate x 1.25 + 20 ms: room for a retry
or two and for neighbours a little out of step, so that in normal running no module's
exchange overruns it and every module's transition is exactly its clock's period."""


def allowance_ms(exchange_ms: float, transition_ms: int, step_ms: int) -> int:
    """Exchange allowance (ms): a module whose exchange ended later than this on its clock
    starts its hold late by the overrun, which pulls it into step with a late neighbour."""
    want = round(exchange_ms * ALLOWANCE_FACTOR + ALLOWANCE_EXTRA_MS)
    return max(1, min(want, transition_ms - step_ms))


def roll_ms(max_colour: int, exchange_ms: float) -> int:
    """Length of the roll call on every module: past the last first-exchange deadline."""
    return round(FIRST_BASE_MS + (max_colour + 2) * FIRST_WINDOW_MS + exchange_ms)


def master_miss_ms(tx_payload: int) -> float:
    """A master's try without a reply (what its clock adds per try): pulse + reply wait is
    ``ReplyBase`` whatever the pulse."""
    return (
        (1 + tx_payload) * byte_ms()
        + REPLY_BASE_UNITS * SERIN_UNIT_MS
        + MASTER_STATEMENTS * (STMT_MS)
    )


def master_ok_ms(pulse_ms: float, tx_payload: int, rx_payload: int) -> float:
    """A master's successful try: its request, the slave's checks and pulse, the reply."""
    return (
        pulse_ms
        + (1 + tx_payload) * byte_ms()
        + (1 + 2 * tx_payload) * STMT_MS
        + pulse_ms
        + (1 + rx_payload) * byte_ms()
        + (MASTER_STATEMENTS + MUTE_STATEMENTS + 2 * rx_payload) * STMT_MS
    )


def linger_ms() -> float:
    """A slave's linger after its reply that hears nothing (the master got the reply):
    ``LINGER_LISTENS`` listens of ``Linger`` back to back, setting it up and ending it."""
    listen = LINGER_UNITS * SERIN_UNIT_MS + (1 + LINGER_STATEMENTS) * STMT_MS
    return LINGER_LISTENS * listen + 4 * STMT_MS


def retry_after_ms() -> float:
    """Latest start of a master's retry after its request ended or after the last reply byte
    it received (its SERIN timeout restarts on every byte): pulse + reply wait is ``ReplyBase``
    whatever the pulse, plus the statements of a miss."""
    return (REPLY_BASE_UNITS + 1) * SERIN_UNIT_MS + MISS_STATEMENTS * STMT_MS


def slave_ok_ms(pulse_ms: float, rx_payload: int, tx_payload: int) -> float:
    """A slave's successful try: on average half its listening before the request starts, the
    request, its checks, one pulse, its reply and a silent linger (a repeated request adds
    this again: the wait for it replaces the silence)."""
    listen = SLAVE_BASE_UNITS * SERIN_UNIT_MS - pulse_ms
    return (
        pulse_ms
        + listen / 2
        + (1 + rx_payload) * byte_ms()
        + (SLAVE_STATEMENTS + MUTE_STATEMENTS + 2 * rx_payload) * STMT_MS
        + pulse_ms
        + (1 + tx_payload) * byte_ms()
        + linger_ms()
    )


def recover_ms(pulse_ms: float) -> float:
    """A slave that caught a damaged or partial request: the listening it came in, the tail,
    a pulse and the wait for the master's next try, about the master's gap between tries."""
    return pulse_ms + REPLY_BASE_UNITS * SERIN_UNIT_MS - pulse_ms


def slave_miss_ms() -> float:
    """A slave's try without a request: pulse + listening is ``SlaveBase`` whatever the pulse."""
    return SLAVE_BASE_UNITS * SERIN_UNIT_MS + SLAVE_STATEMENTS * STMT_MS


def master_gap_ms(pulse_max_ms: float, tx_payload: int, rx_payload: int) -> float:
    """A master's longest time between two pulses: its request, then a reply or the timeout."""
    common = pulse_max_ms + 3 * STMT_MS + (1 + tx_payload) * byte_ms() + STMT_MS
    answered = (
        SLAVE_TURNAROUND_MS
        + 2 * max(0, tx_payload - 1) * STMT_MS  # the slave checks and stores every state
        + (1 + rx_payload) * byte_ms()
        + (1 + 2 * rx_payload) * STMT_MS
        + (1 + MUTE_STATEMENTS) * STMT_MS
        + AFTER_MS
    )
    unanswered = REPLY_BASE_UNITS * SERIN_UNIT_MS + 2 * STMT_MS
    return common + max(answered, unanswered)


def _slave_receive_ms(pulse_max_ms: float, rx_payload: int) -> float:
    """A slave's pulse, then a request arriving at the end of its listening (normal or
    recovery: pulse + timeout is ``SlaveBase`` or ``Recover``, less than one unit) and its
    checks."""
    del pulse_max_ms  # pulse-compensated
    wait = (max(SLAVE_BASE_UNITS, RECOVER_UNITS) + 1) * SERIN_UNIT_MS
    return 4 * STMT_MS + wait + (1 + rx_payload) * byte_ms() + (1 + 2 * rx_payload) * STMT_MS


def slave_gap_ms(pulse_max_ms: float, rx_payload: int, tx_payload: int) -> float:
    """A slave's longest time between two pulses: a request arriving at the end of its listening
    (normal or recovery) and its checks; or, from the pulse before its reply, the reply and a
    silent linger up to the next link's pulse, or the reply, the master's retry (the reply was
    lost) and its checks."""
    receive = _slave_receive_ms(pulse_max_ms, rx_payload)
    reply_end = pulse_max_ms + 2 * STMT_MS + (1 + tx_payload) * byte_ms()
    quiet = (
        reply_end + MUTE_STATEMENTS * STMT_MS + linger_ms() + 2 * RUN_MS + AFTER_MS
    )  # the last link: via the rule slot
    checks = (1 + 2 * rx_payload) * STMT_MS
    # the master's timer ran from its request's end (just before the slave's checks) or from
    # the last reply byte it got; a reply it got whole but corrupt is retried at once
    start = max(retry_after_ms() - checks, reply_end + MISS_STATEMENTS * STMT_MS + pulse_max_ms)
    if tx_payload:  # a dropped header: the payload still restarts the master's timeout
        start = max(start, reply_end + retry_after_ms())
    retry = start + (1 + rx_payload) * byte_ms() + checks
    return max(receive, quiet, retry)


def slave_exchange_ms(pulse_max_ms: float, rx_payload: int, tx_payload: int) -> float:
    """A slave's fault-free time on one wire: a request arriving at the end of its listening,
    its checks, pulse and reply, and the silent linger."""
    return (
        _slave_receive_ms(pulse_max_ms, rx_payload)
        + pulse_max_ms
        + (2 + MUTE_STATEMENTS) * STMT_MS
        + (1 + tx_payload) * byte_ms()
        + linger_ms()
    )


# ---- issue 13 §2: a measured timing file (bstool.timingfile, bstool probe) ------------------
_active = DEFAULT_MODEL
_ESTIMATE = {"STMT_MS": STMT_MS, "HOLD_STMT_MS": HOLD_STMT_MS, "RUN_MS": RUN_MS,
             "PULSOUT_UNIT_MS": PULSOUT_UNIT_MS, "SERIN_UNIT_MS": SERIN_UNIT_MS}  # fmt: skip


def coefficients() -> TimingModel:
    """The timing model the estimates use now: the default, or the one of :func:`measured`."""
    return _active


@contextmanager
def measured(model: TimingModel | None) -> Iterator[None]:
    """Estimate with ``model`` inside the block: statements (STMT_MS, HOLD_STMT_MS) × its
    instruction time ratio, its RUN overhead, PULSOUT and SERIN-timeout units. Not thread-safe
    (compile runs on one thread)."""
    global _active, STMT_MS, HOLD_STMT_MS, RUN_MS, PULSOUT_UNIT_MS, SERIN_UNIT_MS
    if model is None:
        yield
        return
    r = model.instruction_time_ratio.value
    _active = model
    STMT_MS = _ESTIMATE["STMT_MS"] * r
    HOLD_STMT_MS = _ESTIMATE["HOLD_STMT_MS"] * r
    RUN_MS = model.run_us.value / 1000
    PULSOUT_UNIT_MS = model.pulsout_unit_us.value / 1000
    SERIN_UNIT_MS = model.serin_unit_ms.value
    try:
        yield
    finally:
        _active = DEFAULT_MODEL
        STMT_MS, HOLD_STMT_MS, RUN_MS = (
            _ESTIMATE[k] for k in ("STMT_MS", "HOLD_STMT_MS", "RUN_MS")
        )
        PULSOUT_UNIT_MS, SERIN_UNIT_MS = _ESTIMATE["PULSOUT_UNIT_MS"], _ESTIMATE["SERIN_UNIT_MS"]
