"""The module-to-module link of the serve loop: frame bytes, serial settings and the loop's
constants (normative text: protocol/link.md).

The generated PBASIC builds and checks exactly these bytes; :func:`encode` and :func:`parse`
are the Python mirror used by the tests, the test vectors and the twin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

BAUD = 4800
BAUDMODE = 2_500_000 // BAUD - 20 + 32768
"""BS2sx baudmode: 4800 baud, 8N1, true polarity, open drain (+32768), so a shared wire with a
pull-up never has two drivers fighting (bs2sx.md §2)."""
TRANSITION_MOD = 8
"""Headers carry t mod 8: neighbours are within ±1 transition (the join within ±2)."""

# ---- headers (protocol/link.md §3) ------------------------------------------------------------
REQ = 0xA8  # $A8 + t: a master's request (CA: my S^t; NN: the header alone, "take S^(t+1)?")
REP = 0xC8  # $C8 + t: a slave's reply (CA: my S^t; NN: bare, "I show it")
READY = 0x50  # NN: $50 + h, "send me S^(h+1)": the packed states follow (pack_states)
TOOK = 0x98  # NN: $98 + h, "I took S^(h+1)"
WAIT = 0x68  # NN: $68 + t, "alive, not yet"
BEHIND = 0xE8  # CA: $E8 + t, "I am one transition behind you"
WELCOME = 0xD8  # $D8 + t: the answer to a JOIN of a rebooted neighbour
JOIN = 0xB8  # $B8, $B8: "I have just booted"
KINDS = {
    REQ: "REQ",
    REP: "REP",
    READY: "READY",
    TOOK: "TOOK",
    WAIT: "WAIT",
    BEHIND: "BEHIND",
    WELCOME: "WELCOME",
}
NN_ONLY = ("READY", "TOOK", "WAIT")


@dataclass(frozen=True)
class ServeConstants:
    """The serve loop's constants of one model family (PBASIC ``CON``s, manifest ``link``).

    Every one is a policy or a bound of the stamp's own behaviour, never a size from the timing
    model (protocol/link.md §5)."""

    hold_frames: int  # servo frames (tries) a state is shown at least (CA) / the lead shows it (NN)
    reply_wait: int  # master: reply wait, 0.4 ms units, + 0..7 jitter
    listen: int  # slave: listening per try, 0.4 ms units, + 0..7 jitter
    payload_wait: int  # the payload after a header, 0.4 ms units (NN: per byte)
    pace_ms: int  # SEROUT pace between the bytes of a frame
    dead_limit_ms: int  # a wire silent this long (sums of lower bounds of tries) is dead
    power_up_window_ms: int  # the join waits this long for a silent neighbour at power-up
    keepalive_rounds: int  # a master that has its reply still sends every this many rounds
    jitter_units: int = 7  # RANDOM & 7 added to both timeouts
    states_wait: int | None = None  # NN: the packed states after READY, 0.4 ms units per byte
    pace_ticks: int | None = None  # NN: every upstream wire silent this many ticks: pace myself
    ask_tries: int | None = None  # CA: a master's REQs in a row while the slave's state is missing
    lack_tries: int | None = None  # CA: a slave's listens in a row while the master's is missing


CA = ServeConstants(
    hold_frames=26,  # fallback only: a build derives HoldFrames from --period
    reply_wait=16,  # 6.4-9.2 ms: twice the slowest reply start at timing scale 3
    listen=22,  # 8.8-11.6 ms: longer than the master's retry interval, so a retry meets a listen
    payload_wait=8,  # 3.2 ms: one byte (2.08 ms) after the header at the 2 ms pace, with margin
    pace_ms=2,  # above a slow receiver's SERIN re-arm (item time x speed <= 0.54 ms) with margin
    dead_limit_ms=1500,  # the 1 s with margin
    power_up_window_ms=5000,  # the 3 s power-up spread with margin
    keepalive_rounds=4,  # every round doubled a 2-D lead's period; silence must mean "off"
    ask_tries=3,  # the two ends of a wire meet soon after both show S^t (docs/link-redesign.md §7)
    lack_tries=5,  # a listen window longer than a master's asks in a row
)
NN = ServeConstants(
    hold_frames=4,  # the floor: a build derives HoldFrames from --period
    reply_wait=16,  # as CA
    listen=22,  # as CA
    payload_wait=8,  # 3.2 ms as CA: the byte after a JOIN or WELCOME header (10 ms: a 28 ms gap)
    pace_ms=2,  # as CA
    dead_limit_ms=1500,  # DeadTicks = 15 ticks of 100 ms
    power_up_window_ms=4500,  # JoinTicks = 45 ticks of 100 ms
    keepalive_rounds=4,  # as CA
    states_wait=15,  # 6 ms per byte: a byte (2.08 ms) at the 2 ms pace, so a lost byte costs a try
    pace_ticks=30,  # 2 x DeadTicks: a live upstream is heard well before, a dead lead is not
)
SERIN_UNIT_MS = 0.4
"""The unit of a BS2sx SERIN timeout: 0.4 ms (1 ms on the BS2; bs2sx.md, manual p. 394)."""
NN_TICK_MS = 100
"""NN: one silent tick is 100 ms of a sum of lower bounds of the tries."""
CA_QUIET_UNIT_MS = 0.8
"""CA: the unit of the silence clock ``quiet`` (a Byte): every try adds a lower bound of its
own length, so a tick lasts at least its length in real time whatever the stamp's speed and
whichever tries a round skips (keep-alives)."""
CA_TICK_QUIET = 144
"""CA: one silent tick is 144 quiet units (>= 115.2 ms): DeadTicks = 15 fits a Nib."""
CLOCK_MARGIN = 0.95
"""CA lower bounds are clock times (bytes, pace, SERIN timeouts) x 0.95: a resonator up to 5 %
fast still lasts at least that long (the sweep's clock spread is 2 %)."""


@dataclass(frozen=True)
class CaQuiet:
    """CA: the silence clock's constants in quiet units (the programs' TickQuiet, AskQuiet,
    ListenQuiet, HeardQuiet, AskHeardQuiet; the manifest's ``link.*_quiet_units``)."""

    tick: int  # one silent tick
    ask: int  # a master's try that heard nothing: the REQ's two bytes, the pace, the reply wait
    listen: int  # a listen that heard nothing
    heard: int  # a try that heard a byte
    ask_heard: int  # a master's try that heard a byte: the REQ, the pace and that byte


def ca_quiet(k: ServeConstants | None = None) -> CaQuiet:
    """CA: the tick and the lower bounds each try adds to the silence clock."""
    k = k or CA
    unit = CA_QUIET_UNIT_MS / CLOCK_MARGIN
    return CaQuiet(
        tick=CA_TICK_QUIET,
        ask=int((2 * byte_ms() + k.pace_ms + k.reply_wait * SERIN_UNIT_MS) / unit),
        listen=int(k.listen * SERIN_UNIT_MS / unit),
        heard=int(byte_ms() / unit),
        ask_heard=int((3 * byte_ms() + k.pace_ms) / unit),
    )


def serve_constants(nn: bool) -> ServeConstants:
    return NN if nn else CA


def ca_dead_ticks() -> int:
    """CA DeadTicks: >= the dead-limit whatever the timing (one more tick: the first one may
    have begun just before the silence)."""
    return math.ceil(CA.dead_limit_ms / (CA_TICK_QUIET * CA_QUIET_UNIT_MS)) + 1


def nn_dead_ticks() -> int:
    return NN.dead_limit_ms // NN_TICK_MS


def nn_join_ticks() -> int:
    return NN.power_up_window_ms // NN_TICK_MS


# ---- bytes ------------------------------------------------------------------------------------


def encode_state(s: int, t: int = 0) -> int:
    """One state as a self-checking byte: low nibble s, high nibble (15 − s) XOR t.

    The XOR with the frame's t makes a header whose t bit flipped fail the payload check, so a
    frame can never count for another transition; ``t = 0`` is the plain code (WELCOME's CA
    fields)."""
    if not 0 <= s <= 15:
        raise ValueError(f"state {s} is not 0..15")
    return ((15 - s) ^ (t % TRANSITION_MOD)) << 4 | s


def syndrome(b: int, t: int) -> int:
    """0 for a state's payload byte in a frame of ``t``, 12..15 for an age's, else garbled."""
    return (b >> 4) ^ (b & 15) ^ 15 ^ (t % TRANSITION_MOD)


def decode_state(b: int, t: int = 0) -> int | None:
    """The state in a payload byte, or None if its check nibble is wrong for ``t``."""
    return b & 15 if syndrome(b, t) == 0 else None


MAX_AGE = 63
AGE_BASE = 192  # a payload value 192 + age: its syndrome (see syndrome) is 12..15


def encode_value(v: int, t: int) -> int:
    """A CA REQ/REP payload byte of the value ``v``: a state 0..15, or 192 + an age 0..63.
    Low nibble v & 15, high nibble (v & 15) ^ 15 ^ t ^ (v >> 4), so a state codes as
    :func:`encode_state` and an age has the syndrome 12 + age // 16 (protocol/link.md §3)."""
    if not (0 <= v <= 15 or AGE_BASE <= v <= AGE_BASE + MAX_AGE):
        raise ValueError(f"payload value {v} is neither a state 0..15 nor an age 192..255")
    lo = v & 15
    return (lo ^ 15 ^ (t % TRANSITION_MOD) ^ (v >> 4)) << 4 | lo


def encode_age(age: int, t: int) -> int:
    """A keep-alive's payload: the sender's hold clock in AgeUnits (0..63, saturated)."""
    if not 0 <= age <= MAX_AGE:
        raise ValueError(f"age {age} is not 0..{MAX_AGE}")
    return encode_value(AGE_BASE + age, t)


def decode_age(b: int, t: int) -> int | None:
    """The age in a keep-alive's payload byte, or None if it is not an age for ``t``. A single
    flipped bit never turns a state into an age or an age into a state (syndromes two bits
    apart); it can turn one age into another (the hold clock is a policy, never correctness)."""
    syn = syndrome(b, t)
    if syn < 12:
        return None
    return (syn - 12) << 4 | (b & 15)


@dataclass(frozen=True)
class Frame:
    """A frame as a module program reads it. ``states``: CA REQ/REP one state; WELCOME (CA:
    got + 2·fresh, nb, nbp, state, prev, t; NN: the lead's state). NN REQ is the header alone:
    its states follow READY as a packed frame (:func:`pack_states`). ``age``: a CA REQ/REP
    keep-alive carries the sender's hold clock instead of its state (protocol/link.md §4.2)."""

    kind: str  # REQ REP READY TOOK WAIT BEHIND WELCOME JOIN
    t: int = 0
    states: tuple[int, ...] = ()
    age: int | None = None


def _bare(kind: str, nn: bool) -> bool:
    """Header-only frames: TOOK, WAIT, BEHIND, and in NN also REQ, REP and READY."""
    return kind in ("TOOK", "WAIT", "BEHIND") or (nn and kind in ("REQ", "REP", "READY"))


def encode(frame: Frame, *, nn: bool) -> bytes:
    """The bytes of ``frame`` on the wire (protocol/link.md §3)."""
    t = frame.t % TRANSITION_MOD
    if frame.age is not None and (nn or frame.kind not in ("REQ", "REP") or frame.states):
        raise ValueError("only a CA REQ or REP without a state carries an age")
    if frame.kind == "JOIN":
        return bytes([JOIN, JOIN])
    base = {v: k for k, v in KINDS.items()}[frame.kind]
    if _bare(frame.kind, nn):
        return bytes([base + t])
    if frame.kind == "WELCOME" and not nn:
        return bytes([base + t, *(encode_state(s) for s in frame.states)])
    if frame.age is not None:
        return bytes([base + t, encode_age(frame.age, t)])
    return bytes([base + t, *(encode_state(s, t) for s in frame.states)])


def payload_length(kind: str, *, nn: bool) -> int:
    """Payload bytes after the header of ``kind``."""
    if kind == "JOIN":
        return 1
    if _bare(kind, nn):
        return 0
    return 1 if nn or kind != "WELCOME" else 6


def parse(data: bytes, *, nn: bool) -> Frame | None:
    """Check a received frame as the module program does: header, length and every check
    nibble (CA WELCOME: its last field repeats t). None means "not received"."""
    if not data:
        return None
    if data[0] == JOIN:
        return Frame("JOIN") if data == bytes([JOIN, JOIN]) else None
    kind = KINDS.get(data[0] & 0xF8)
    if kind is None or (kind in NN_ONLY and not nn) or (kind == "BEHIND" and nn):
        return None
    t = data[0] & 7
    if len(data) != 1 + payload_length(kind, nn=nn):
        return None
    plain = kind == "WELCOME" and not nn
    if not nn and kind in ("REQ", "REP"):
        age = decode_age(data[1], t)
        if age is not None:
            return Frame(kind, t, (), age)
    got = [decode_state(b, 0 if plain else t) for b in data[1:]]
    if any(s is None for s in got):
        return None
    values = tuple(s for s in got if s is not None)
    if plain and values[-1] != t:
        return None
    return Frame(kind, t, values)


# ---- NN: the packed states after READY(h) ----------------------------------------------------


MAX_PACKED_STATES = 5
"""A packed frame's check detects every pair of bit errors in two bytes up to 3 bytes (5
states, legs of 6 modules): 12 error patterns in 15 non-zero checks (:func:`pack_states`)."""


def packed_length(states: int) -> int:
    """Bytes of ``states`` packed states: two to a byte, and the check nibble."""
    return states // 2 + 1


def _mix(check: int) -> int:
    """M(x) = x XOR (x rotated right by one), on the 4-bit check."""
    return (check ^ check >> 1 ^ check << 3) & 15


def _fold(data: bytes) -> int:
    """The check of a packed frame: ck = M(ck) ^ (hi ^ lo), byte by byte from ck = 0."""
    check = 0
    for b in data:
        check = _mix(check) ^ (b >> 4) ^ (b & 15)
    return check


def pack_states(states: tuple[int, ...] | list[int], h: int) -> bytes:
    """The master's answer to READY(h): S^(h+1) of modules 0..j, two to a byte (byte k =
    s(2k) << 4 + s(2k+1)); the last byte's high nibble is the check, its low nibble the odd
    state or 0. The check makes the frame fold (:func:`_fold`) to h. A bit flipped in byte k of
    K changes the fold by M^(K-1-k) of one bit: one bit, two adjacent bits or two bits two
    apart (K <= 3), never 0 and never the same for two bytes, so every single-bit error and
    every pair of them in two bytes is detected, and a frame of another h fails
    (protocol/link.md §4.6)."""
    if not states or any(not 0 <= s <= 15 for s in states):
        raise ValueError(f"states {states} are not one or more of 0..15")
    n = len(states)
    if n > MAX_PACKED_STATES:
        raise ValueError(f"{n} states: a packed frame carries at most {MAX_PACKED_STATES}")
    odd = states[-1] if n % 2 else 0
    pairs = bytes(states[2 * k] << 4 | states[2 * k + 1] for k in range(n // 2))
    check = _mix(_fold(pairs)) ^ odd ^ (h % TRANSITION_MOD)
    return pairs + bytes([check << 4 | odd])


def unpack_states(data: bytes, h: int, states: int) -> tuple[int, ...] | None:
    """The ``states`` states of a packed frame received after READY(h), or None if its length
    or its check is wrong (the program checks the fold only: a wrong length is a StatesWait
    timeout)."""
    if len(data) != packed_length(states) or _fold(data) != h % TRANSITION_MOD:
        return None
    nibbles = [v for b in data[:-1] for v in (b >> 4, b & 15)]
    if states % 2:
        nibbles.append(data[-1] & 15)
    return tuple(nibbles)


def byte_ms(baud: int = BAUD) -> float:
    """Time on the wire of one 8N1 byte in milliseconds."""
    return 10_000 / baud
