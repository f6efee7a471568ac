"""Timing model of the serve loop on a BS2sx, for the manifest's estimates only: the nominal
period and the longest gap between servo pulses (protocol/link.md §6).

Model (docs/compile.md): every PBASIC statement costs :data:`STMT_MS` (a BS2sx runs about
10,000 instructions/s, bs2sx.md §1) plus its own time: PULSOUT its pulse, PAUSE its argument,
SEROUT 10 bit times per byte and the pace between bytes, SERIN its timeout when nothing comes,
RUN :data:`RUN_MS`. No constant of the programs is sized from these numbers: every wait of the
serve loop is a policy or a bound of the stamp's own behaviour (bstool.wire.link), and
correctness rests on the handshakes.
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.timingfile import DEFAULT as DEFAULT_MODEL
from bstool.timingfile import TimingModel
from bstool.wire.link import ServeConstants, byte_ms

STMT_MS = 0.1
"""A statement at the default model's speed (instruction time ratio 1)."""
RUN_MS = 0.3
SERIN_UNIT_MS = 0.4  # BS2sx SERIN timeout unit
PULSOUT_UNIT_MS = 0.0008
HOLD_STMT_MS = 0.102
"""Mean time of a short statement (calibrated on the twin's interpreter model, 20 us + 2 us
per token bit; STMT_MS is the general upper estimate); kept for the timing file's ratio."""
PAD_PIN = 13
"""An unconnected pin (the probe program's delay pin)."""

TRY_STATEMENTS = 6
"""The statements of one try besides its PULSOUT, SEROUT and SERIN (frames, RANDOM, hdr = 0,
the IFs on the header, the jump)."""
TURNAROUND_STATEMENTS = 5
"""A slave from the end of a request to its reply's SEROUT: the checks, heard, the IFs on the
header, the pulse before the reply."""
CA_ASK_STATEMENTS = 31
"""CA: a master's answered try besides its pulses, REQ and REP: its payload (Age, Encode), the
reply's decode (Syndrome, Aged), the round's checks (Due, the next wire's keep-alive test)."""
CA_SLAVE_TURN_STATEMENTS = 16
"""CA: a slave from the end of a REQ to its reply's pulse: the hold clock, Syndrome, the IFs on
the header and the payload, Aged or the store, Encode."""
CA_LISTEN_STATEMENTS = 18
"""CA: a listen that hears nothing, besides its pulse and its wait: frames, RANDOM, hdr, the
tries-in-a-row tests, Due, the next wire's test."""
END_STATEMENTS = 12
"""CA: the end of a transition: the tick, the hold and got checks, prev, the rule's lookup."""
CA_EXCHANGE_ROUNDS = 0.6
"""CA: a transition besides its hold, in rounds of the busiest module (the sum of its usual
tries): the hold runs from the module's own switch and the keep-alives carry it to the latest
switch around (protocol/link.md §4.2), so a transition is the hold plus the latest module's
wait for its next Due test and the switch. Fitted on the twin (-T 20, periods 0.475 and 0.7 s:
ca1d about 30 ms on a 40 ms round, 2-D about 37 ms on 75 ms; docs/compile.md "Period"); it
only sets HoldFrames for --period and the reported estimates."""
CA_FRAME_RATIO = 1.04
"""CA: a hold frame's real length over its estimate (FrameTime): the hold clock leaves out the
tick's bookkeeping and the skipped keep-alives (fitted with CA_EXCHANGE_ROUNDS: 1.03-1.05)."""
GAP_STATEMENTS = 20
"""The statements between tries that the try counts above leave out (the tick bookkeeping,
jumps between wires); calibrated on the twin's interpreter (docs/compile.md)."""
SERVO_HOLDS_MS = 50
"""An analog hobby servo (the Futaba S5301 is one; no datasheet of its own found) holds its
position while pulses come at most this far apart and relaxes after it (Parallax forum thread
90233: repetition 20-50 ms, "after 50 mSec of no pulse seen, the servo relaxes"; MicroPython
wiki "Servos": analog servos need 20-65 updates a second). Up to 25 ms (40 Hz) the refresh rate
makes no difference at all (owiki "Servo control"). docs/compile.md "Servo gaps"."""
SERVO_NEUTRAL_MS = 25
CA_LOST_STATEMENTS = 50
"""CA: a master's try whose REP header came at the end of the reply wait and whose payload
was lost (line noise): from its pulse, besides the REQ, the wait, the header and PayloadWait:
the pulse itself, the round's checks (Due, the next wire's keep-alive test) and the next try's
statements before its pulse (Age, Encode); calibrated on the twin (25.1 ms measured on the
2-D leads with 1 % noise, docs/compile.md "Servo gaps"), so the bound covers it."""
NN_STORE_STATEMENTS = 4
"""NN: a slave between the packed states and the pulse before TOOK, besides one store per
state and one fold statement per byte: the check's test, the joining test (protocol/link.md
§4.6)."""
NN_MEETINGS = 5.6
"""NN: the meetings on a transition's critical path at one hop: the master's REQ heard by a
listening slave (READY, the states and TOOK in one try), and its REP once the slave shows it;
each costs about (slave round / listen) master rounds (docs/compile.md, calibrated there)."""
NN_IDLE_PAUSE_MS = 16
"""NN: the lead's idle frame (a keep-alive round skipped) pauses this long (nn_main.bsx.j2)."""
NN_LEAD_GAP_STATEMENTS = 60
"""NN: the lead's longest gap besides its idle pause: the idle frame's round end, the 100 ms
tick's bookkeeping and the advance (Pending) before the next pulse; calibrated on the twin
(21.4 ms measured on the leads of nnsin/nnsig, docs/compile.md)."""
NN_IDLE_STATEMENTS = 10
"""NN: the statements of the lead's idle frame and its round's end (nn_main.bsx.j2 L0Idle,
the bypass and tick tests, Ticked, Steady)."""


def packed_bytes(states: int) -> int:
    """NN: the bytes of ``states`` packed two to a byte after READY, with the check nibble."""
    return states // 2 + 1


def frame_ms(nbytes: int, k: ServeConstants) -> float:
    """One SEROUT of ``nbytes`` at the pace ``k.pace_ms``."""
    return nbytes * byte_ms() + max(0, nbytes - 1) * k.pace_ms


@dataclass(frozen=True)
class CompileTiming:
    """The timing model the estimates use: the default or a measured one (``compile --timing
    F``), as a value passed to the plans, never a process-wide setting."""

    model: TimingModel = DEFAULT_MODEL

    @property
    def stmt_ms(self) -> float:
        return STMT_MS * self.model.instruction_time_ratio.value

    @property
    def hold_stmt_ms(self) -> float:
        return HOLD_STMT_MS * self.model.instruction_time_ratio.value

    @property
    def run_ms(self) -> float:
        return self.model.run_us.value / 1000

    @property
    def pulsout_unit_ms(self) -> float:
        return self.model.pulsout_unit_us.value / 1000

    @property
    def serin_unit_ms(self) -> float:
        return self.model.serin_unit_ms.value

    def statements(self, n: float) -> float:
        return n * self.stmt_ms

    def wait_ms(self, units: float) -> float:
        return units * self.serin_unit_ms

    def transition_end_ms(self) -> float:
        """CA: from the last try of a transition to the first of the next: the rule slot and
        back."""
        return 2 * self.run_ms + self.statements(END_STATEMENTS)

    def master_try_ms(
        self, pulse_ms: float, tx: int, rx: int, k: ServeConstants, *, nn: bool
    ) -> float:
        """A master's usual answered try: its pulse, its request, the slave's turnaround (its
        pulse before the reply) and the reply. NN: the header-only poll and a bare reply (WAIT,
        REP, READY's header); the states follow only once per transition (:meth:`take_ms`)."""
        req, rep = (1, 1) if nn else (1 + tx, 1 + rx)
        return (
            2 * pulse_ms
            + frame_ms(req, k)
            + frame_ms(rep, k)
            + self.statements(TURNAROUND_STATEMENTS + TRY_STATEMENTS)
        )

    def take_ms(self, pulse_ms: float, states: int, k: ServeConstants) -> float:
        """NN: what a take adds to a poll answered READY: the master's pulse and the packed
        states, the slave's stores, its pulse and TOOK."""
        return (
            2 * pulse_ms
            + frame_ms(packed_bytes(states), k)
            + frame_ms(1, k)
            + self.statements(NN_STORE_STATEMENTS + packed_bytes(states) + states + TRY_STATEMENTS)
        )

    def _ca_exchange_ms(self, k: ServeConstants, pulse_ms: float) -> float:
        """CA: REQ(t), the slave's turnaround and its pulse (``pulse_ms``), REP(t)."""
        return 2 * frame_ms(2, k) + self.statements(CA_SLAVE_TURN_STATEMENTS) + pulse_ms

    def ca_ask_ms(self, k: ServeConstants, pulse_ms: float) -> float:
        """CA, the hold clock: a master's answered try besides its first pulse (most tries in
        the hold are keep-alives, answered): the exchange, the master's pulse after it
        (``pulse_ms``: the robot's middle pulse), the statements."""
        return self._ca_exchange_ms(k, pulse_ms) + pulse_ms + self.statements(CA_ASK_STATEMENTS)

    def ca_listen_ms(self, k: ServeConstants) -> float:
        """CA, the hold clock: a listen that hears nothing besides its pulse (the jitter at
        its mean)."""
        return self.wait_ms(k.listen + k.jitter_units / 2) + self.statements(CA_LISTEN_STATEMENTS)

    def ca_heard_ms(self, k: ServeConstants, pulse_ms: float) -> float:
        """CA, the hold clock: what a listen that hears a REQ and answers adds to a quiet one:
        the REQ (arriving, on average, half-way through the listen), the turnaround, the reply
        and its pulse (``pulse_ms``: the robot's middle pulse)."""
        return self._ca_exchange_ms(k, pulse_ms) - self.wait_ms(k.listen + k.jitter_units / 2) / 2

    def listen_ms(self, pulse_ms: float, k: ServeConstants, *, jitter: float) -> float:
        """A slave's try that hears nothing: its pulse and the whole listen."""
        return pulse_ms + self.wait_ms(k.listen + jitter) + self.statements(TRY_STATEMENTS)

    def idle_ms(self, pulse_ms: float) -> float:
        """NN: the lead's plain servo frame while its keep-alive round is skipped, with the
        round's end (the bypass and tick tests, the hold checks)."""
        return pulse_ms + NN_IDLE_PAUSE_MS + self.statements(NN_IDLE_STATEMENTS)

    def miss_ms(self, pulse_ms: float, k: ServeConstants) -> float:
        """NN: a master's header-only poll that nobody answers: its pulse, the header and the
        whole reply wait (the jitter at its mean)."""
        return (
            pulse_ms
            + frame_ms(1, k)
            + self.wait_ms(k.reply_wait + k.jitter_units / 2)
            + self.statements(TRY_STATEMENTS)
        )

    def slave_receive_gap_ms(
        self, rx: int, k: ServeConstants, *, nn: bool, master_pulse_ms: float = 0.0
    ) -> float:
        """A slave's longest time between two pulses: a request starting at the end of the
        longest listen, received whole, then the statements to the pulse before its reply. NN:
        the request is a header (or transition 0's two-byte JOIN); or, from the pulse before
        READY, READY, the master's pulse and the packed states, the check's fold and the stores."""
        listen = self.wait_ms(k.listen + k.jitter_units)
        if not nn:
            return (
                listen
                + frame_ms(1 + rx, k)
                + self.statements(TRY_STATEMENTS + TURNAROUND_STATEMENTS + 2 * rx + GAP_STATEMENTS)
            )
        return max(
            listen + frame_ms(2, k) + self.statements(TRY_STATEMENTS + GAP_STATEMENTS),
            frame_ms(1, k)
            + master_pulse_ms
            + frame_ms(packed_bytes(rx), k)
            + self.statements(
                TURNAROUND_STATEMENTS + NN_STORE_STATEMENTS + packed_bytes(rx) + rx + GAP_STATEMENTS
            ),
        )

    def lost_payload_gap_ms(self, tx: int, k: ServeConstants) -> float:
        """CA: a master's longest time between two pulses when the REP's payload is lost: its
        REQ, the longest reply wait, the REP header at its end, PayloadWait, then the
        statements to the next try's pulse (:data:`CA_LOST_STATEMENTS`)."""
        return (
            frame_ms(1 + tx, k)
            + self.wait_ms(k.reply_wait + k.jitter_units)
            + frame_ms(1, k)
            + self.wait_ms(k.payload_wait)
            + self.statements(CA_LOST_STATEMENTS)
        )

    def master_gap_ms(self, tx: int, rx: int, k: ServeConstants, *, nn: bool) -> float:
        """A master's longest time between two pulses: its request (NN: the poll, or the packed
        states), the longest reply wait with a reply starting at its end, and the next try's
        statements."""
        first = max(1, packed_bytes(tx)) if nn else 1 + tx
        reply = 1 if nn else 1 + rx
        return (
            frame_ms(first, k)
            + self.wait_ms(k.reply_wait + k.jitter_units)
            + frame_ms(reply, k)
            + self.statements(2 * TRY_STATEMENTS + GAP_STATEMENTS)
        )


DEFAULT = CompileTiming()
