"""The interpreter's I/O boundary: serial links in one virtual time, SERIN blocking and
timeouts, lost bytes, PULSOUT reports, RUN across slots.

``run_network`` below is the smallest scheduler the twin needs: always advance the stamp with
the smallest horizon; deliver each byte at once to the stamps wired to the sending pin.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from interpreter_asm import Asm, const, op, var

from bstool.tokenizer.tokens import Binary, Instruction, VarSize
from hil_mock.stamp import NotInTwin, SimpleEeprom, Stamp, StampIO, Status, timing

VECTORS = Path(__file__).resolve().parent / "vectors" / "tokenizer"  # copied from ../shared
needs_vectors = pytest.mark.skipif(not VECTORS.is_dir(), reason="tests/vectors/tokenizer missing")

BAUD2400 = 1021
W = VarSize.WORD


class Net(StampIO):
    """Wires: a byte sent on (stamp, pin) is offered to every pin connected to it."""

    def __init__(self) -> None:
        self.links: dict[tuple[int, int], list[tuple[Stamp, int]]] = {}
        self.delivered = 0
        self.lost = 0
        self.pulses: list[tuple[str, int, int, int]] = []

    def connect(self, a: Stamp, pa: int, b: Stamp, pb: int) -> None:
        self.links.setdefault((id(a), pa), []).append((b, pb))
        self.links.setdefault((id(b), pb), []).append((a, pa))

    def serial_out(self, stamp: Stamp, pin: int, value: int, start_ns: int, mode: int) -> None:
        for other, opin in self.links.get((id(stamp), pin), []):
            if other.deliver_byte(opin, value, start_ns, mode):
                self.delivered += 1
            else:
                self.lost += 1

    def pulse(self, stamp: Stamp, pin: int, start_ns: int, width_ns: int, level: int) -> None:
        self.pulses.append((stamp.name, pin, start_ns, width_ns))


def run_network(stamps: list[Stamp], until_ns: int) -> None:
    while True:
        s = min(stamps, key=lambda x: x.horizon)
        if s.horizon >= until_ns:
            return
        if s.status is Status.WAITING:
            s.expire_wait()  # every other stamp is past the deadline: nothing can arrive
            continue
        limit = min([o.horizon for o in stamps if o is not s] + [until_ns])
        s.run_until(limit)


def echo_pair(b_pause_ms: int = 0) -> tuple[Stamp, Stamp, Net]:
    # A: PAUSE 5
    #    Top: SEROUT 1,[x]; SERIN 0, 100 (40 ms), Lost, [y]; x = y + 1; IF x < 20 THEN Top; END
    #    Lost: lost = lost + 1; GOTO Top            (x = W3, y = W4, lost = W5)
    a = Asm()
    a.stmt(Instruction.PAUSE, [const(5)])
    a.here("Top")
    a.serout(1, BAUD2400, [[var(W, 3)]])
    a.serin(0, BAUD2400, [var(W, 4, write=True)], timeout=100, tlabel="Lost")
    a.let([var(W, 4), const(1), op(Binary.ADD)], var(W, 3, write=True))
    a.if_([var(W, 3), const(20), op(Binary.LT)], "Top")
    a.end()
    a.here("Lost")
    a.let([var(W, 5), const(1), op(Binary.ADD)], var(W, 5, write=True))
    a.goto("Top")
    # B: PAUSE p; Loop: SERIN 0, 1250 (500 ms), Loop, [v]; PAUSE 2; SEROUT 1, [v + 1]; GOTO Loop
    # (the PAUSE 2 gives A time to enter SERIN: without it B's reply is lost, as on a stamp)
    b = Asm()
    b.stmt(Instruction.PAUSE, [const(b_pause_ms)])
    b.here("Loop")
    b.serin(0, BAUD2400, [var(W, 3, write=True)], timeout=1250, tlabel="Loop")
    b.stmt(Instruction.PAUSE, [const(2)])
    b.serout(1, BAUD2400, [[var(W, 3), const(1), op(Binary.ADD)]])
    b.goto("Loop")
    net = Net()
    sa = Stamp(SimpleEeprom([a.image()]), io=net, name="A")
    sb = Stamp(SimpleEeprom([b.image()]), io=net, name="B")
    net.connect(sa, 1, sb, 0)
    net.connect(sb, 1, sa, 0)
    return sa, sb, net


def test_echo_between_two_modules() -> None:
    sa, sb, net = echo_pair()
    run_network([sa, sb], until_ns=2_000_000_000)
    assert sa.status is Status.ENDED
    assert sa.memory.word(3) == 20  # 10 round trips: 0 -> 1 -> 2 ... 19 -> 20
    assert sa.memory.word(5) == 0  # nothing lost
    assert sb.memory.word(3) == 18  # the last value B received
    assert (net.delivered, net.lost) == (20, 0)
    byte = timing.byte_ns(BAUD2400)
    assert byte == 4_164_000  # 10 bits at 2.5 MHz / 1041
    # PAUSE 5, then 20 bytes on the wire one after the other, B's 10 PAUSE 2, and a few
    # instructions per hop
    wire = 5_000_000 + 20 * byte + 10 * 2_000_000
    assert wire < sa.t < wire + 20 * 300_000
    assert sb.status is Status.WAITING  # B waits again (timeout 500 ms after its last byte)


def test_byte_sent_while_receiver_busy_is_lost() -> None:
    sa, sb, net = echo_pair(b_pause_ms=30)
    run_network([sa, sb], until_ns=2_000_000_000)
    assert sa.status is Status.ENDED
    assert sa.memory.word(5) == 1  # first byte lost (B in PAUSE, no receive buffer)
    assert sa.memory.word(3) == 20
    assert net.lost == 1
    assert sa.t > 40_000_000  # A waited out its 100 x 0.4 ms timeout once


def test_network_run_is_deterministic() -> None:
    runs = []
    for _ in range(2):
        sa, sb, net = echo_pair(b_pause_ms=30)
        run_network([sa, sb], until_ns=2_000_000_000)
        runs.append((sa.t, sb.t, bytes(sa.ram), bytes(sb.ram), net.delivered, net.lost))
    assert runs[0] == runs[1]


def test_deliver_byte_window() -> None:
    _, sb, _ = echo_pair()
    sb.run()  # B blocks in SERIN on pin 0
    w = sb.wait
    assert sb.status is Status.WAITING and w is not None
    assert (w.pin, w.deadline) == (0, w.since + 1250 * 400_000)
    assert not sb.deliver_byte(0, 7, w.since - 1)  # before it listened
    assert not sb.deliver_byte(0, 7, w.deadline)  # at the timeout
    assert not sb.deliver_byte(1, 7, w.since)  # other pin
    assert not sb.deliver_byte(0, 7, w.since, mode=240)  # other bit rate
    assert sb.deliver_byte(0, 7, w.since + 5)
    assert sb.memory.word(3) == 7
    assert sb.t == w.since + 5 + timing.byte_ns(BAUD2400)


def test_serin_timeout_jumps_to_label() -> None:
    sa, _, _ = echo_pair()
    sa.run()  # SEROUT (nobody listens), then SERIN
    assert sa.status is Status.WAITING
    deadline = sa.wait.deadline  # type: ignore[union-attr]
    sa.expire_wait()
    assert sa.t == deadline and sa.status is Status.RUNNING
    sa.step()  # Lost: lost = lost + 1
    assert sa.memory.word(5) == 1


@needs_vectors
def test_select_case_host_input_on_pin_16() -> None:
    s = Stamp(SimpleEeprom([(VECTORS / "select_case_values" / "slot0.eeprom").read_bytes()]))
    replies = []
    for ch in b"fxl\rB":
        s.run()
        assert s.status is Status.WAITING and s.wait is not None and s.wait.pin == 16
        s.debug.clear()
        assert s.deliver_byte(16, ch, s.t + 1_000_000)
        s.run()
        replies.append(bytes(s.debug))
    # f -> action 1 (CASE 1 TO 2): "move"; x -> 15 (CASE > 14): ASC ? key; l -> 3 (ELSE): DEC;
    # CR -> 0: GOTO Again silently; B -> 2: "move"
    assert replies == [b"move\r", b'key = "x"\r', b"3\r", b"", b"move\r"]


@needs_vectors
def test_serin_formatters_and_timeout() -> None:
    # value = W3, byteIn = byte 10
    s = Stamp(SimpleEeprom([(VECTORS / "serin_timeout_formatters" / "slot0.eeprom").read_bytes()]))
    s.run()
    assert s.wait is not None and s.wait.pin == 7
    assert s.deliver_byte(7, 0x41, s.t)
    assert s.memory.byte(10) == 0x41
    s.run()  # SERIN Rx, Baud, 2500, NoReply, [DEC value]
    for ch in b"ab123\r":  # non-digits before the number are skipped; CR ends it
        assert s.deliver_byte(7, ch, s.t)
    assert s.memory.word(3) == 123
    with pytest.raises(NotInTwin, match="SERIN_FLOW"):
        s.run()
    # again, with silence after the first byte: 2500 x 0.4 ms = 1 s, then NoReply: value = 0
    s.reset()
    s.memory.set_word(3, 999)
    s.run()
    s.deliver_byte(7, 0x41, s.t)
    s.run()
    start = s.t
    s.expire_wait()
    assert s.t - start == 1_000_000_000
    s.run()  # NoReply: value = 0, GOTO Start, blocks in the first SERIN again
    assert s.memory.word(3) == 0 and s.status is Status.WAITING


@needs_vectors
def test_robot_ca_module_alone() -> None:
    net = Net()
    img = (VECTORS / "robot_ca_module" / "slot0.eeprom").read_bytes()
    s = Stamp(SimpleEeprom([img]), io=net, name="L0.M0")
    run_network([s], until_ns=1_000_000_000)
    # alone, both SERINs time out and inner = outer = state; next = nibble (idx & 1) of
    # Rules[idx >> 1], idx = state * 17: 7 -> $DE hi = 13 -> $9D hi = 9 -> $13 hi = 1
    # -> $C4 hi = 12 -> $24 lo = 4
    widths = [w for _, pin, _, w in net.pulses if pin == 12]
    states = [13] * 5 + [9] * 5 + [1] * 5 + [12] * 5 + [4] * 5
    assert widths[:25] == [(st * 111 + 1042) * 800 for st in states]
    starts = [t for _, _, t, _ in net.pulses]
    # one frame: PULSOUT + PAUSE 18 + NEXT; one exchange: 2 x (2 bytes at 2400 + 20 ms)
    frame = starts[1] - starts[0]
    assert 18e6 + widths[0] < frame < 18e6 + widths[0] + 400_000
    period = starts[5] - starts[0]
    assert 4 * frame + 2 * (2 * 4_164_000 + 20e6) < period < 5 * frame + 2 * 30e6


@needs_vectors
@pytest.mark.parametrize(("jumper", "expected"), [(0, [1, 0, 1, 0]), (1, [3, 3, 3, 3])])
def test_multi_robot_rules_run_across_slots(jumper: int, expected: list[int]) -> None:
    folder = VECTORS / "multi_robot_rules"
    ee = SimpleEeprom([(folder / f"slot{n}.eeprom").read_bytes() for n in range(3)])
    net = Net()
    s = Stamp(ee, io=net, name="M")
    s.set_input(8, jumper)  # RoleJumper: low = control rule (slot 1), high = leg rule (slot 2)
    states = []
    slots = []
    for _ in range(100_000):
        if len(states) == 4:
            break
        if s.status is Status.WAITING:
            s.expire_wait()  # alone on the bus: every SERIN times out
        else:
            s.step()
        slots.append(s.slot)
        if s.slot == 0 and s.pc == s.program.start and slots[-2:-1] != [0]:
            states.append(s.memory.scratch[0])  # the state PUT by the rule slot
    # CR: state 0 -> CRTable[0] = $F1 low = 1 -> idx $11: CRTable[8] = $03 high = 0 -> ...
    # LR: state 0 -> LRTable[0] = $23 low = 3 -> idx $33: LRTable[25] = $30, >> 4 = 3
    assert states == expected
    assert set(slots) == {0, 1 + jumper}
    widths = {w for _, _, _, w in net.pulses}
    assert widths == {(st * 111 + 1042) * 800 for st in [0, *expected[:-1]]}


def test_erased_slot_is_a_clear_fault() -> None:
    from hil_mock.stamp import StampFault

    s = Stamp(SimpleEeprom([b"\xff" * 2048]))  # start address field all ones: bit 16383
    with pytest.raises(StampFault, match="no valid program"):
        s.run()
    empty = Stamp(SimpleEeprom([bytes(2048)]))  # all zero: start 0 decodes as END
    assert empty.run() is Status.ENDED


def test_return_without_gosub_is_a_fault() -> None:
    from hil_mock.stamp import StampFault

    a = Asm()
    a.code(Instruction.RETURN)
    with pytest.raises(StampFault, match="RETURN without GOSUB"):
        Stamp(SimpleEeprom([a.image()])).run()
