"""The module-to-module link: frame bytes (protocol/vectors/link_frames.json), topology
(link_topology.json), deadlock freedom and pins."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import traced_controller
from hypothesis import given
from hypothesis import strategies as st

from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans
from bstool.compile.topology import links, module_links, reads
from bstool.controllers import CA_MODELS, MODELS, NN_MODELS, load_controller
from bstool.controllers.controller import make_controller
from bstool.errors import BuildError
from bstool.moduleid import ModuleId, all_modules
from bstool.wire import link

VECTORS = Path(__file__).resolve().parents[1] / "protocol" / "vectors"


def test_frame_vectors() -> None:
    data = json.loads((VECTORS / "link_frames.json").read_text())
    for case in data["frames"]:
        nn = case["family"] == "nn"
        want = link.Frame(case["kind"], case["t"] if case["kind"] != "JOIN" else 0,
                          tuple(case["states"]))  # fmt: skip
        raw = link.encode(want, nn=nn)
        assert raw.hex(" ").upper() == case["bytes"]
        assert link.parse(raw, nn=nn) == want
    for case in data["keepalives"]:
        want = link.Frame(case["kind"], case["t"], (), case["age"])
        raw = link.encode(want, nn=False)
        assert raw.hex(" ").upper() == case["bytes"]
        assert link.parse(raw, nn=False) == want
    for case in data["packed"]:
        raw = link.pack_states(case["states"], case["h"])
        assert raw.hex(" ").upper() == case["bytes"]
        assert link.unpack_states(raw, case["h"], len(case["states"])) == tuple(case["states"])
    for case in data["rejected"]:
        raw = bytes.fromhex(case["bytes"])
        if "h" in case:  # a packed states frame
            assert link.unpack_states(raw, case["h"], case["states"]) is None, case
        else:
            assert link.parse(raw, nn=case["family"] == "nn") is None, case
    for ex in data["exchanges"]:
        nn = "NN" in ex["description"]
        for step in ex["steps"]:
            raw = bytes.fromhex(step["bytes"])
            if step.get("packed"):
                assert link.unpack_states(raw, step["h"], step["packed"]) is not None
            else:
                assert link.parse(raw, nn=nn) is not None, step


def test_topology_vectors() -> None:
    data = json.loads((VECTORS / "link_topology.json").read_text())
    for model, wires in data["models"].items():
        got = [lk.to_json() for lk in links(model, data["legs"], data["modules"])]
        assert got == wires, model


@given(
    kind=st.sampled_from(["REQ", "REP", "READY", "WELCOME"]),
    nn=st.booleans(),
    t=st.integers(0, 7),
    states=st.lists(st.integers(0, 15), min_size=6, max_size=6),
)
def test_frame_round_trip(kind: str, nn: bool, t: int, states: list[int]) -> None:
    if kind == "READY" and not nn:
        assert link.parse(bytes([link.READY + t]), nn=False) is None  # NN only
        return
    n = link.payload_length(kind, nn=nn)
    frame = link.Frame(kind, t, tuple(states[:n]))
    if kind == "WELCOME" and not nn:
        frame = link.Frame(kind, t, (*states[:5], t))
    raw = link.encode(frame, nn=nn)
    assert link.parse(raw, nn=nn) == frame
    # a header never looks like a payload byte, so a receiver that starts mid-frame rejects it
    assert all(link.decode_state(raw[0], u) is None for u in range(8))
    if frame.states and not (kind == "WELCOME" and not nn):  # t is in every payload's check
        other = bytes([raw[0] ^ 1, *raw[1:]])
        assert link.parse(other, nn=nn) is None


@given(
    h=st.integers(0, 7),
    states=st.lists(st.integers(0, 15), min_size=1, max_size=link.MAX_PACKED_STATES),
    flip=st.integers(0, 23),
    other=st.integers(0, 23),
)
def test_packed_states(h: int, states: list[int], flip: int, other: int) -> None:
    """NN states after READY(h): round trip; every single-bit error, every pair of bit errors
    in two bytes and another h rejected."""
    raw = link.pack_states(states, h)
    assert len(raw) == link.packed_length(len(states)) == len(states) // 2 + 1
    assert link.unpack_states(raw, h, len(states)) == tuple(states)
    bits = 8 * len(raw)
    first, second = flip % bits, other % bits
    bad = bytearray(raw)
    bad[first // 8] ^= 1 << (first % 8)
    assert link.unpack_states(bytes(bad), h, len(states)) is None
    if first // 8 != second // 8:
        bad[second // 8] ^= 1 << (second % 8)
        assert link.unpack_states(bytes(bad), h, len(states)) is None
    assert all(link.unpack_states(raw, u, len(states)) is None for u in range(8) if u != h)


def test_a_states_frame_longer_than_its_check_is_refused() -> None:
    with pytest.raises(ValueError, match="at most 5"):
        link.pack_states([1] * (link.MAX_PACKED_STATES + 1), 0)


@given(s=st.integers(0, 15), t=st.integers(0, 7), flip=st.integers(0, 7))
def test_single_bit_errors_are_caught(s: int, t: int, flip: int) -> None:
    assert link.decode_state(link.encode_state(s, t) ^ (1 << flip), t) is None


@given(
    age=st.integers(0, link.MAX_AGE),
    s=st.integers(0, 15),
    t=st.integers(0, 7),
    flip=st.integers(0, 7),
    u=st.integers(1, 7),
)
def test_ages_and_states_never_pass_for_each_other(
    age: int, s: int, t: int, flip: int, u: int
) -> None:
    """A keep-alive's age (protocol/link.md §3): round trip; a state's byte codes as before;
    one flipped payload bit, or a header of another t, never turns an age into a state or a
    state into an age."""
    b = link.encode_age(age, t)
    assert link.decode_age(b, t) == age and link.decode_state(b, t) is None
    assert link.encode_value(s, t) == link.encode_state(s, t)
    assert link.decode_age(link.encode_state(s, t), t) is None
    assert link.decode_state(b ^ (1 << flip), t) is None
    assert link.decode_age(link.encode_state(s, t) ^ (1 << flip), t) is None
    assert link.decode_state(b, t ^ u) is None  # a header's t flipped: never a state
    frame = link.Frame("REP", t, (), age)
    assert link.parse(link.encode(frame, nn=False), nn=False) == frame
    with pytest.raises(ValueError, match="age"):
        link.encode_age(link.MAX_AGE + 1, t)
    with pytest.raises(ValueError, match="carries an age"):
        link.encode(link.Frame("REQ", t, (), age), nn=True)


def test_bare_answers_are_two_bits_apart() -> None:
    """NN TOOK, REP and WAIT, and READY against every header a master hears (protocol/link.md
    §3): no single flipped bit turns one into another (a WAIT read as REP deadlocked a leg)."""
    for t in range(link.TRANSITION_MOD):
        bare = [link.TOOK + t, link.REP + t, link.WAIT + t]
        pairs = [(a, b) for a in bare for b in bare if a != b]
        pairs += [(link.READY + t, b) for b in (*bare, link.WELCOME + t, link.JOIN)]
        for a, b in pairs:
            assert bin(a ^ b).count("1") >= 2, (hex(a), hex(b))


DECLARED = {
    "Baud", "HoldFrames", "ReplyWait", "Listen", "Pace", "PayloadWait", "StatesWait", "DeadTicks",
    "PaceTicks", "JoinTicks", "JoinMs", "TickQuiet", "AskQuiet", "ListenQuiet", "HeardQuiet",
    "AskHeardQuiet", "FrameTime", "MasterTry", "ListenTry", "HeardTry", "AskTries", "LackTries",
}  # fmt: skip
"""The CONs the manifest accounts for (test_every_program_declares_the_manifest_constants)."""


def test_every_program_declares_the_manifest_constants(tmp_path: Path) -> None:
    """The constants bstool.wire.link gives the manifest are the CONs of every compiled program
    (nn_main.bsx.j2 spells them out, the CA templates take them from the plan)."""
    import re

    from bstool.compile import compile_controller

    for model in MODELS:
        res = compile_controller(traced_controller(model), tmp_path / model, tokenize=False)
        man = res.manifest
        for m in man.modules:
            text = (tmp_path / model / m.entry).read_text()
            con = dict(re.findall(r"^(\w+)\s+CON\s+(\d+)", text, re.M))
            k = man.link
            assert int(con["Baud"]) == k.baudmode
            assert int(con["HoldFrames"]) == k.hold_frames, (model, m.label)
            assert int(con["ReplyWait"]) == k.reply_wait_units
            assert int(con["Listen"]) == k.listen_units
            assert int(con["Pace"]) == k.pace_ms
            assert int(con["PayloadWait"]) == k.payload_wait_units
            assert int(con["DeadTicks"]) == m.dead_ticks
            if model in NN_MODELS:
                assert int(con["StatesWait"]) == k.states_wait_units
                assert int(con["PaceTicks"]) == k.pace_ticks
                assert int(con["DeadTicks"]) * link.NN_TICK_MS == k.dead_limit_ms
                assert int(con["JoinTicks"]) * link.NN_TICK_MS == k.power_up_window_ms
            else:
                assert int(con["JoinMs"]) == k.power_up_window_ms
                assert k.states_wait_units is None and k.pace_ticks is None
                assert int(con["TickQuiet"]) == k.tick_quiet_units
                assert int(con["AskQuiet"]) == k.ask_quiet_units
                assert int(con["ListenQuiet"]) == k.listen_quiet_units
                assert int(con["HeardQuiet"]) == k.heard_quiet_units
                assert int(con["AskHeardQuiet"]) == k.ask_heard_quiet_units
                assert int(con["FrameTime"]) == k.frame_units
                assert int(con["MasterTry"]) == k.master_try_units
                assert int(con["ListenTry"]) == k.listen_try_units
                assert int(con["HeardTry"]) == k.heard_try_units
                # a keep-alive's age: the hold in 63 steps, rounded up (protocol/link.md §4.2)
                assert re.search(r"^AgeUnit\s+CON\s+HoldTime \+ 62 / 63\b", text, re.M)
                assert int(con["AskTries"]) == k.ask_tries
                assert int(con["LackTries"]) == k.lack_tries
                dead_ms = (m.dead_ticks - 1) * k.tick_quiet_units * link.CA_QUIET_UNIT_MS
                assert dead_ms >= k.dead_limit_ms
            assert set(con) <= DECLARED, set(con) - DECLARED  # a new CON: into the manifest


def test_baudmode() -> None:
    assert link.BAUDMODE == 500 + 32768  # 4800 baud true (bs2sx.md §2) + open drain


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize(("legs", "modules"), [(5, 6), (1, 1), (2, 2), (3, 5), (4, 3)])
def test_links_cover_reads_and_are_deadlock_free(model: str, legs: int, modules: int) -> None:
    wires = links(model, legs, modules)
    for mid in all_modules(legs, modules):
        mine = module_links(wires, mid)
        pins = [lk.pin(mid) for lk in mine]
        assert len(set(pins)) == len(pins) and all(0 <= p <= 3 for p in pins)
        peers = {lk.peer(mid) for lk in mine}
        if model in CA_MODELS:
            colours = [lk.colour for lk in mine]
            assert colours == sorted(set(colours)), "one link per colour, run in colour order"
            assert {c for c in reads(model, legs, modules, mid) if c != mid} <= peers
        else:
            want = {ModuleId(mid.leg, mid.module + d) for d in (-2, -1, 1, 2)}
            assert peers == {p for p in want if 0 <= p.module < modules}
            # receive (chain, then bypass), then send (chain, then bypass)
            order = [lk.peer(mid).module - mid.module for lk in mine]
            assert order == [d for d in (-1, -2, 1, 2) if 0 <= mid.module + d < modules]
        for lk in mine:
            assert lk.master < lk.slave  # the module earlier in canonical order talks first
    if model in NN_MODELS:  # chain j-1 -> j: colour j-1; bypass j-1 -> j+1: colour j+1
        for lk in wires:
            assert lk.bypass == (lk.slave.module == lk.master.module + 2)
            assert lk.colour == (lk.slave.module if lk.bypass else lk.master.module)


def test_ca2d_lead_has_four_wires() -> None:
    wires = links("ca2dsing", 5, 6)
    lead = module_links(wires, ModuleId(2, 0))
    assert {str(lk.peer(ModuleId(2, 0))) for lk in lead} == {"1.0", "3.0", "2.1", "2.5"}
    assert {lk.pin(ModuleId(2, 0)) for lk in lead} == {0, 1, 2, 3}


def test_link_vector_files_are_up_to_date() -> None:
    """The generator builds the vectors from protocol/link.md's rules alone (no bstool code)."""
    import importlib.util

    path = VECTORS / "make_link_vectors.py"
    assert "import bstool" not in path.read_text() and "from bstool" not in path.read_text()
    spec = importlib.util.spec_from_file_location("make_link_vectors", path)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for name, text in module.render().items():
        assert text == (VECTORS / name).read_text(), "run protocol/vectors/make_link_vectors.py"


def test_dead_limit_is_at_least_a_second_and_a_half() -> None:
    """DeadTicks (protocol/link.md §5): silent ticks, each a lower bound of tries, >= 1.5 s."""
    ctrl = load_controller(traced_controller("ca2dsing"))
    tick_ms = link.CA_TICK_QUIET * link.CA_QUIET_UNIT_MS
    for plan in build_plans(ctrl, DEFAULT, 0.475, "0" * 8):
        assert (plan.dead_ticks - 1) * tick_ms >= link.CA.dead_limit_ms
        assert plan.dead_ticks <= 15  # ti is a Nib
    # each try adds at most its shortest length on a resonator 5 % fast (a sum of lower bounds)
    byte = 10 / 4.8  # ms at 4800 baud
    q = link.ca_quiet()
    ask, listen, heard, ask_heard = q.ask, q.listen, q.heard, q.ask_heard
    assert q.tick == link.CA_TICK_QUIET
    unit = link.CA_QUIET_UNIT_MS
    assert ask * unit <= 0.95 * (2 * byte + link.CA.pace_ms + 0.4 * link.CA.reply_wait)
    assert listen * unit <= 0.95 * 0.4 * link.CA.listen
    assert 0 < heard * unit <= 0.95 * byte
    assert heard < ask_heard and ask_heard * unit <= 0.95 * (3 * byte + link.CA.pace_ms)
    # the largest add keeps the Byte clock below 256 before it is wrapped by a tick
    assert link.CA_TICK_QUIET - 1 + max(ask, listen, heard, ask_heard) < 256
    assert link.nn_dead_ticks() * link.NN_TICK_MS >= 1500
    assert link.nn_join_ticks() * link.NN_TICK_MS >= 3000 + link.nn_dead_ticks()


@pytest.mark.parametrize("modules", [6, 7])
def test_nn_legs_longer_than_the_states_check_are_refused(modules: int) -> None:
    """Module j relays j + 1 states: a leg of 7 modules would need a 4-byte frame."""
    weights = [[[int(a < j) for j in range(modules)] for a in range(modules)]] * 2
    ctrl = make_controller("nnsig", [3, 9], weights=weights)
    if modules == 6:
        plans = build_plans(ctrl, DEFAULT, 0.475, "0" * 8)
        longest = max(len(ll.send) for plan in plans for ll in plan.links)
        assert longest == link.MAX_PACKED_STATES
        return
    with pytest.raises(BuildError, match="longer than the 5 its check protects"):
        build_plans(ctrl, DEFAULT, 0.475, "0" * 8)
