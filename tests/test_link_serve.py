"""The serve-loop link (protocol/link.md), CA and NN: it stays exact where the old roll-call
protocol failed (a spread power-up, resets of a lead and of a middle module, shorter than the
dead-limit) and under timing scale 3 and the combined perturbations with byte noise; a module
failed from power-up is dead after the power-up window (``--fail``), one dying mid-run after the
dead-limit (``--die``, against ``failed_at``). NN (protocol/link.md): the same cases with the
servo fed at nominal timing, a middle module dead from power-up (the bypass around it) and dying
mid-run, a lead dying mid-run and dead from power-up (module 1 paces the leg on its held state),
and a cut chain link (both ends treat each other as dead). No physics, T = 6.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TracedBuild

from bstool.buildfile import Build
from bstool.controllers import load_controller
from bstool.moduleid import ModuleId
from bstool.wire import link
from hil_mock.outage import nn_cut_reference
from hil_mock.perturb import Perturbation, Reset
from hil_mock.robot import RobotTwin, load_build
from hil_mock.twin_result import TwinResult

T = 6
RESET_AT_S = 1.5  # no roll call: its first transitions come after about 0.5 s

CASES: dict[str, tuple[Perturbation, float]] = {
    "start spread 3 s": (Perturbation(start_spread=3.0, seed=2), 0.0),
    "reset lead 0.0 for 0.4 s": (Perturbation(resets=(Reset("0.0", RESET_AT_S, 0.4),)), 0.0),
    "reset middle 2.3 for 0.8 s": (Perturbation(resets=(Reset("2.3", RESET_AT_S, 0.8),)), 0.0),
    "timing scale 3": (Perturbation(timing_scale=3.0), 0.0),
    "harsh + noise 1 %": (
        Perturbation(
            timing_scale=2.0,
            timing_spread=0.2,
            clock_spread=0.02,
            start_spread=3.0,
            item_time_us=100.0,
            resets=(Reset("2.3", 5.0, 0.4),),
            seed=3,
        ),
        0.01,
    ),
}


@pytest.fixture(scope="module")
def serve_builds(traced_build: TracedBuild) -> dict[str, Build]:
    return {m: load_build(traced_build(m)) for m in ("ca1d", "ca2dsing", "nnsin", "nnsig")}


def _assert_exact_with_a_dead_module(
    build: Build, kind: str, mid: ModuleId, timeout_s: float | None = None
) -> None:
    """``kind`` "fail": dead from power-up; "die": dying at transition 3."""
    ctrl = load_controller(build.controller_file)
    if kind == "fail":
        twin = RobotTwin(build, physics=False, failed=[mid])
        want = ctrl.states(T, failed=[mid])
    else:
        twin = RobotTwin(build, physics=False, die={mid: 3})
        want = ctrl.states(T, failed_at={mid: 3})
    result = twin.run(T, timeout_s=timeout_s)
    assert not result.stalled
    assert np.array_equal(result.state_array(build.legs, build.modules, T), want)


def _assert_exact_under(build: Build, case: str) -> tuple[RobotTwin, TwinResult]:
    """The healthy reference, every state, under the perturbation ``case``."""
    p, noise = CASES[case]
    twin = RobotTwin(build, noise=noise, seed=p.seed, physics=False, perturb=p)
    result = twin.run(T)
    got = result.state_array(build.legs, build.modules, T)
    want = load_controller(build.controller_file).states(T)
    assert not result.stalled
    assert np.array_equal(got, want), f"{build.manifest.controller.model} under {case}"
    return twin, result


@pytest.mark.parametrize("model", ["ca1d", "ca2dsing"])
@pytest.mark.parametrize(("kind", "mid"), [("fail", ModuleId(2, 3)), ("die", ModuleId(0, 0))])
def test_the_serve_loop_waits_out_dead_modules(
    serve_builds: dict[str, Build], model: str, kind: str, mid: ModuleId
) -> None:
    _assert_exact_with_a_dead_module(serve_builds[model], kind, mid)


MARK = {"ca1d": "PayloadWait", "ca2dsing": "PayloadWait", "nnsin": "READY", "nnsig": "READY"}
"""A word only the model family's serve-loop program holds (CA: the payload wait; NN: READY)."""


@pytest.mark.parametrize("model", list(MARK))
@pytest.mark.parametrize("case", list(CASES))
def test_the_serve_loop_stays_exact(serve_builds: dict[str, Build], model: str, case: str) -> None:
    """CA and the NN relay: exact under every case; the servo fed at nominal timing (NN: a
    REQ's states are at most 3 bytes)."""
    build = serve_builds[model]
    assert MARK[model] in (build.root / "modules" / "L0.M1" / "main.bsx").read_text()
    twin, result = _assert_exact_under(build, case)
    p, _ = CASES[case]
    outage = twin.perturb.reset_modules()
    gaps = [g for m, g in result.servo_gaps.items() if m not in outage]
    if p.timing_scale == 1.0 and p.timing_spread == 0.0:
        assert max(gaps) < 0.025


@pytest.mark.parametrize("model", ["nnsin", "nnsig"])
@pytest.mark.parametrize(
    ("kind", "mid"),
    [
        ("fail", ModuleId(2, 3)),
        ("fail", ModuleId(0, 1)),
        ("die", ModuleId(2, 3)),
        ("die", ModuleId(2, 0)),
        ("fail", ModuleId(2, 0)),
    ],
)
def test_the_nn_relay_bypasses_dead_modules(
    serve_builds: dict[str, Build], model: str, kind: str, mid: ModuleId
) -> None:
    """j - 1 relays to j + 1 on the bypass once j is past the power-up window / the dead-limit
    (for module 1: the lead to module 2); a dead lead's module 1 paces the leg on the held state
    (from power-up: after the window and PaceTicks, about 12 s, past the default stall limit)."""
    timeout = 30.0 if kind == "fail" and mid.module == 0 else None
    _assert_exact_with_a_dead_module(serve_builds[model], kind, mid, timeout)


NN_CUTS = [  # the lead's link, a middle one, the last one, a bypass
    (ModuleId(2, 0), ModuleId(2, 1)),
    (ModuleId(0, 2), ModuleId(0, 3)),
    (ModuleId(2, 4), ModuleId(2, 5)),
    (ModuleId(2, 1), ModuleId(2, 3)),
]


@pytest.mark.parametrize("model", ["nnsin", "nnsig"])
@pytest.mark.parametrize("cut", NN_CUTS)
def test_the_nn_relay_survives_a_cut_link(
    serve_builds: dict[str, Build], model: str, cut: tuple[ModuleId, ModuleId]
) -> None:
    """A chain link A-B cut from power-up: A treats B as dead (the bypass to B + 1 carries B's
    held state), B hears nobody upstream and paces on the held R^0 of 0..A; every module but B
    equals ``--fail B``, B equals its leg's upstream failed. A cut bypass changes nothing. (B, or
    module 1 of a cut lead link, starts after the power-up window and PaceTicks: about 12 s, past
    the default stall limit at T = 6.)"""
    build = serve_builds[model]
    ctrl = load_controller(build.controller_file)
    a, b = cut
    result = RobotTwin(build, physics=False, cut=[cut]).run(T, timeout_s=30.0)
    if b.module - a.module == 2:
        want = ctrl.states(T)
    else:
        want = ctrl.states(T, failed=[b])
        upstream = [ModuleId(b.leg, i) for i in range(b.module)]
        want[:, b.leg, b.module] = ctrl.states(T, failed=upstream)[:, b.leg, b.module]
    assert not result.stalled
    assert np.array_equal(result.state_array(build.legs, build.modules, T), want)


class _TappedTwin(RobotTwin):
    """Records every byte a stamp sends: (start ns, sender, pin, value)."""

    def __init__(self, build: Build) -> None:
        super().__init__(build, physics=False)
        self.sent: list[tuple[int, ModuleId, int, int]] = []

    def _route(self, mid: ModuleId, pin: int, value: int, start_ns: int, mode: int) -> None:
        self.sent.append((start_ns, mid, pin, value))
        super()._route(mid, pin, value, start_ns, mode)


@pytest.mark.parametrize("model", ["nnsin", "nnsig"])
def test_the_stamps_pack_states_as_the_spec_says(
    serve_builds: dict[str, Build], model: str
) -> None:
    """Every states frame a stamp sends after READY(h) is bstool.wire.link.pack_states of the
    states 0..j of transition h + 1 (mod 8) of the reference: the PBASIC fold and the Python
    one agree byte for byte, for frames of 1, 2 and 3 bytes."""
    build = serve_builds[model]
    twin = _TappedTwin(build)
    result = twin.run(T)
    assert not result.stalled
    want = load_controller(build.controller_file).states(T + 2)  # the leads run ahead
    master_end = {(w.slave, w.slave_pin): (w.master, w.master_pin) for w in build.manifest.links}
    ready: dict[tuple[ModuleId, int], int] = {}  # master end -> h of the READY it was sent
    frames: dict[tuple[ModuleId, int], list[int]] = {}
    seen = {1: 0, 2: 0, 3: 0}
    for _, mid, pin, value in sorted(twin.sent, key=lambda e: e[0]):
        if (mid, pin) in master_end and value & 0xF8 == link.READY:
            end = master_end[(mid, pin)]
            ready[end], frames[end] = value & 7, []
        elif (end := (mid, pin)) in ready:
            frames[end].append(value)
            if len(frames[end]) == link.packed_length(mid.module + 1):
                h = ready.pop(end)
                raw = bytes(frames.pop(end))
                ts = [t for t in range(T + 3) if t % 8 == (h + 1) % 8]
                assert any(
                    raw == link.pack_states(list(want[t, mid.leg, : mid.module + 1]), h) for t in ts
                ), (mid, h, raw.hex(" "))
                seen[len(raw)] += 1
    assert all(seen.values()), seen


NN_CUTS_IN_RUN = [  # (model, cut, at s): a middle chain wire, the last one
    ("nnsig", (ModuleId(2, 2), ModuleId(2, 3)), 2.0),
    ("nnsin", (ModuleId(2, 2), ModuleId(2, 3)), 4.4),
    ("nnsig", (ModuleId(2, 4), ModuleId(2, 5)), 3.0),
]


def _cut_in_run(build: Build, cut: tuple[ModuleId, ModuleId], at: float) -> tuple[bool, int]:
    twin = RobotTwin(build, physics=False, cut_at={cut: at})
    result = twin.run(12, timeout_s=40.0)
    dies, want = nn_cut_reference(twin, load_controller(build.controller_file), 12)
    assert list(dies) == [cut[1]] and not result.stalled
    return bool(np.array_equal(result.state_array(build.legs, build.modules, 12), want)), dies[
        cut[1]
    ]


@pytest.mark.parametrize(("model", "cut", "at"), NN_CUTS_IN_RUN, ids=str)
def test_an_nn_chain_wire_cut_in_a_running_robot_is_its_downstream_end_dying(
    serve_builds: dict[str, Build], model: str, cut: tuple[ModuleId, ModuleId], at: float
) -> None:
    """j - (j + 1) cut at ``at`` s: j + 1 hears nobody upstream and holds the last state it
    took, j treats it as dead and feeds j + 2 on the bypass: every module equals `bstool
    states --fail-at j+1@T` (T: the last transition j + 1 showed before it could pace)."""
    exact, died = _cut_in_run(serve_builds[model], cut, at)
    assert exact and died >= 2


def test_the_leads_wire_cut_in_a_running_robot(serve_builds: dict[str, Build]) -> None:
    """nnsig, 2.0-2.1 cut at 2.5 s: module 1 paces on its held lead state and keeps its chain
    wire to 2.2 busy; 2.2, fed by the lead's bypass, listened there only every 4th round, missed
    the lead for a dead-limit and then took module 1's stale states (transition 10 on; a strict
    xfail until 2.2 listened on a feeding bypass every round, issue 28 §2)."""
    exact, _ = _cut_in_run(serve_builds["nnsig"], (ModuleId(2, 0), ModuleId(2, 1)), 2.5)
    assert exact


def test_the_module_after_a_cut_at_this_instant_of_leg_0(serve_builds: dict[str, Build]) -> None:
    """nnsin, 0.1-0.2 cut at 4 s: 0.2 (cut off, showing S^7) and 0.3 sent their keep-alives in
    the same round of four, and two loops of one length phase-locked: each poll of 0.2 fell
    outside 0.3's listen for 2.6 s, 0.2 marked 0.3 dead and fed 0.4 a stale frame on the
    bypass. A master wire silent for ti ticks is polled in more rounds (every round from
    ti = 3, as CA does), which breaks the lock (protocol/link.md §4.6; failed before)."""
    exact, _ = _cut_in_run(serve_builds["nnsin"], (ModuleId(0, 1), ModuleId(0, 2)), 4.0)
    assert exact


def test_twin_cli_cuts_a_wire_in_a_running_robot(
    traced_build: TracedBuild, capsys: pytest.CaptureFixture[str]
) -> None:
    from bstool.cli import main

    build = traced_build("nnsig")
    args = ["twin", str(build), "--cut", "2.2-2.3@2", "--no-physics", "-T", "8", "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "EQUAL" in out and "cut L2.M2-L2.M3 at 2 s" in out and "--die L2.M3@3" in out
