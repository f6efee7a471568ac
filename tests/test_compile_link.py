"""The module-to-module link: frame bytes (protocol/vectors/link_frames.json), topology
(link_topology.json), deadlock freedom and pins."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bstool.builtin import builtin_controller
from bstool.compile import timing
from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans
from bstool.compile.topology import links, module_links, reads
from bstool.controllers import CA_MODELS, MODELS, NN_MODELS, load_controller
from bstool.moduleid import ModuleId, all_modules
from bstool.wire import link

VECTORS = Path(__file__).resolve().parents[1] / "protocol" / "vectors"


def test_frame_vectors() -> None:
    data = json.loads((VECTORS / "link_frames.json").read_text())
    for case in data["frames"]:
        reply = case["kind"] == "reply"
        raw = link.encode_frame(reply, case["t"], case["states"])
        assert raw.hex(" ").upper() == case["bytes"]
        frame = link.decode_frame(raw, reply=reply, t=case["t"], payload=len(case["states"]))
        assert frame is not None and list(frame.states) == case["states"]
    for case in data["rejected"]:
        raw = bytes.fromhex(case["bytes"])
        reply = case["kind"] == "reply"
        assert link.decode_frame(raw, reply=reply, t=case["t"], payload=case["payload"]) is None
    for ex in data["exchanges"]:
        for step in ex["steps"]:
            assert bytes.fromhex(step["bytes"])[0] & 0xF0 in (0xA0, 0xC0)


def test_topology_vectors() -> None:
    data = json.loads((VECTORS / "link_topology.json").read_text())
    for model, wires in data["models"].items():
        got = [lk.to_json() for lk in links(model, data["legs"], data["modules"])]
        assert got == wires, model


@given(
    reply=st.booleans(),
    t=st.integers(0, 7),
    states=st.lists(st.integers(0, 15), min_size=1, max_size=15),
)
def test_frame_round_trip(reply: bool, t: int, states: list[int]) -> None:
    raw = link.encode_frame(reply, t, states)
    frame = link.decode_frame(raw, reply=reply, t=t, payload=len(states))
    assert frame == link.Frame(reply, t, tuple(states))
    # a header never looks like a payload byte, so a receiver that starts mid-frame rejects it
    assert link.decode_state(raw[0]) is None
    assert link.decode_frame(raw, reply=not reply, t=t, payload=len(states)) is None
    assert link.decode_frame(raw, reply=reply, t=(t + 1) % 8, payload=len(states)) is None


@given(s=st.integers(0, 15), flip=st.integers(0, 7))
def test_single_bit_errors_are_caught(s: int, flip: int) -> None:
    assert link.decode_state(link.encode_state(s) ^ (1 << flip)) is None


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


def test_next_dead_header_is_two_bits_from_the_others() -> None:
    """The NN reply `$F8 + t` (protocol/link.md §3): one flipped bit never makes or hides it,
    and like every header it fails the payload check."""
    for t in range(link.TRANSITION_MOD):
        flagged = link.REPLY_NEXT_DEAD_BASE + t
        for other in (link.REPLY_BASE + t, link.REQUEST_BASE + t):
            assert bin(flagged ^ other).count("1") == 2
        assert link.decode_state(flagged) is None


def test_nn_pair_guards() -> None:
    """Two NN neighbours dying (protocol/link.md §5): a chain master learns from its slave's
    reply that the module after it is dead (its bypass to that module), and a bypass master with
    an upstream neighbour gives up early while its chain wire is dead, so that it is back before
    that neighbour's deadline however early the neighbour is."""
    ctrl = load_controller(builtin_controller("nnsin"))
    for plan in build_plans(ctrl, DEFAULT, 0.475, "0" * 8):
        j = plan.mid.module
        for ll in plan.links:
            if ll.master and not ll.link.bypass and j + 2 < ctrl.modules:
                assert plan.links[ll.next_dead].peer == ModuleId(plan.mid.leg, j + 2)
            if not ll.master and not ll.link.bypass and j + 1 < ctrl.modules:
                assert plan.links[ll.reports_dead].peer == ModuleId(plan.mid.leg, j + 1)
            if ll.master and ll.link.bypass:
                if j == 0:
                    assert ll.near_deadline == 0  # the lead: nobody upstream to be back for
                    continue
                up = next(u.deadline for u in plan.links if not u.master and not u.link.bypass)
                late = max(d.deadline for d in plan.links if d.master) + plan.hold_step
                early = max(plan.exch_ms, late - plan.hold_ms)
                back = ll.near_deadline + plan.hold_step - plan.hold_ms + early
                assert back + timing.NEAR_SAFETY_MS <= up
                assert timing.LATE_MS <= ll.near_deadline < ll.deadline
