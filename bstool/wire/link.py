"""The module-to-module link: frame bytes and serial settings (normative text: protocol/link.md).

The generated PBASIC builds and checks exactly these bytes; this module is the Python mirror
used by the tests, the test vectors and the twin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

BAUD = 4800
BAUDMODE = 2_500_000 // BAUD - 20 + 32768
"""BS2sx baudmode: 4800 baud, 8N1, true polarity, open drain (+32768), so a shared wire with a
pull-up never has two drivers fighting (bs2sx.md §2)."""

REQUEST_BASE = 0xA8
"""Header of a master's frame: $A8 + (t mod 8)."""
REPLY_BASE = 0xC8
"""Header of a slave's reply: $C8 + (t mod 8)."""
REPLY_NEXT_DEAD_BASE = 0xF8
"""NN: header of the reply of module j on the chain wire from j-1 when j has marked its own next
module j+1 dead: $F8 + (t mod 8). Module j-1 then marks its bypass to j+1 dead too, so that if j
dies later it does not wait on a bypass nobody answers (protocol/link.md §5). Two bits away from
$C8 (and from $A8), so no single flipped bit makes or hides it."""
TRANSITION_MOD = 8

REPLY_BASE_UNITS = 19
"""A master's pulse plus its reply wait, in the BS2sx's 0.4 ms units (7.6 ms): the SERIN timeout
for the reply is ``ReplyBase - pulse / 500`` (5.4-7.0 ms; the reply starts within ~1.5 ms). The
constant gap between tries lets a slave that caught only the tail of a request listen again
before the next try (timing.SLAVE_BASE_UNITS)."""

RECOVER_UNITS = 17
"""A slave's pulse plus its listening (6.8 ms; SERIN timeout ``Recover - pulse / 500``) after it
caught a damaged or partial request: begun within ``SlaveBase`` of the request's end, it lasts
past the start of the master's next try; and since the timeout restarts on every byte, a partial
frame caught in it still leaves the slave listening again before the try after that (pulse +
timeout < the master's ``ReplyBase`` gap between tries), so retries can never lock step with
the slave's pulses."""

SILENT_TRANSITIONS = 2
"""After the roll call, a neighbour silent up to the deadline in this many transitions running is
marked dead like one silent in the roll call (never waited for again; NN bypasses switch on).
Two, not one: a live neighbour is marked dead only if two exchanges in a row are lost up to the
deadline (one is lost with about 5e-7 chance at 1 % byte noise, protocol/link.md §4), since the
mark is for good; more than two would slow the robot for more transitions after a death."""

LINGER_UNITS = 10
"""Timeout of each of a slave's listens after its reply (4.0 ms): plus a pulse it is shorter
than the gap between a master's tries, so a damaged retry caught in the linger (the timeout
restarts after its last byte) leaves the slave listening again before the next try."""

LINGER_LISTENS = 3
"""A slave's listens after its reply, back to back: together (12 ms + statements) they last past the
second byte of a master's retry, which starts at the latest ``ReplyBase`` plus a few statements
after the last reply byte the master got (if the reply was lost or damaged), so even a retry
whose header was lost is heard. Silence through all of them ends the exchange (protocol/link.md
§4)."""


def encode_state(s: int) -> int:
    """One state as a self-checking byte: high nibble 15 − s, low nibble s."""
    if not 0 <= s <= 15:
        raise ValueError(f"state {s} is not 0..15")
    return (15 - s) << 4 | s


def decode_state(b: int) -> int | None:
    """The state in a payload byte, or None if the check nibble is wrong."""
    if (b >> 4) + (b & 15) != 15:
        return None
    return b & 15


@dataclass(frozen=True)
class Frame:
    reply: bool
    t: int  # transition number mod 8
    states: tuple[int, ...]


def encode_frame(reply: bool, t: int, states: Sequence[int]) -> bytes:
    """Header ($A8/$C8 + t mod 8) followed by one self-checking byte per state."""
    base = REPLY_BASE if reply else REQUEST_BASE
    return bytes([base + t % TRANSITION_MOD, *(encode_state(s) for s in states)])


def decode_frame(data: bytes, *, reply: bool, t: int, payload: int) -> Frame | None:
    """Check a received frame as the module program does: length, header and every check nibble.

    None means "not received": the module keeps waiting (or, after its deadline, uses the
    neighbour's last known state).
    """
    if len(data) != 1 + payload:
        return None
    base = REPLY_BASE if reply else REQUEST_BASE
    if data[0] != base + t % TRANSITION_MOD:
        return None
    states = [decode_state(b) for b in data[1:]]
    if any(s is None for s in states):
        return None
    return Frame(reply, t % TRANSITION_MOD, tuple(s for s in states if s is not None))


def byte_ms(baud: int = BAUD) -> float:
    """Time on the wire of one 8N1 byte in milliseconds."""
    return 10_000 / baud
