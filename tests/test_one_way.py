"""One-way wires (issue 28 §3): ``bstool twin --cut 'A>B[@S]'``, ``TwinOptions(one_way=)``. A's
bytes to B are lost, B's reach A; the link falls back on both ends to what a cut wire does
(protocol/link.md §4.5 "One-way wires") and the twin compares with that reference, saying so in
a note. On the twin without physics.

The direction in which a master's (NN: the upstream module's) bytes are lost is a cut for both
ends at once (the other end answers only what it hears). The other direction needed the link's
fallback: a CA master that holds its slave dead sends its age, never its state, and a slave
that gets an age while it lacks the master's state counts it as silence (before, the slave kept
taking the master's states while the master held it dead: 5 of 30 modules differed,
``0.1>0.0``). An NN module whose answers upstream are lost heard its upstream's polls and
never paced (until 2026-12-07); now a READY that no states follow makes it deaf on that wire
(protocol/link.md §4.6 "one-way"), and its upstream's polls stop counting as hearing it.
"""

from __future__ import annotations

import pytest

from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module
from hil_mock.perturb import Perturbation
from hil_mock.robot import load_build
from hil_mock.session import TwinOptions, TwinReport, clock_mismatches, run_twin

T = 14


def _one_way(text: str) -> dict[tuple[ModuleId, ModuleId], float]:
    pair, _, at = text.partition("@")
    a, b = pair.split(">")
    return {(parse_module(a), parse_module(b)): float(at or 0.0)}


def _run(build: object, one_way: str, **kw: object) -> TwinReport:
    options = TwinOptions(transitions=T, one_way=_one_way(one_way), physics=False, **kw)  # type: ignore[arg-type]
    return run_twin(load_build(build), options)  # type: ignore[arg-type]


CA_CASES = [
    # (model, A>B[@S]); in each pair the first loses the master's bytes, the second the slave's
    ("ca1d", "0.1>0.2"),
    ("ca1d", "0.2>0.1"),
    ("ca1d", "0.1>0.2@3"),
    ("ca1d", "0.2>0.1@3"),
    ("ca2dsing", "0.0>0.1"),
    ("ca2dsing", "0.1>0.0"),
    ("ca2dsing", "1.0>2.0@3"),
    ("ca2dsing", "2.0>1.0@3"),
    ("ca2ddiff", "0.0>0.5"),
    ("ca2ddiff", "0.5>0.0"),
    ("ca2ddiff", "4.0>4.1@2.5"),
    ("ca2ddiff", "4.1>4.0@2.5"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("model", "one_way"), CA_CASES)
def test_a_ca_one_way_wire_falls_back_to_a_cut(traced_build, model: str, one_way: str) -> None:
    report = _run(traced_build(model), one_way)
    assert not report.result.stalled
    assert report.ok, report.check.first_mismatch
    notes = " ".join(report.check.notes)
    assert "one-way wire" in notes and "compared" in notes


NN_CASES = [
    pytest.param("nnsin", "2.2>2.3", id="nnsin-upstream-lost-power-up"),
    pytest.param("nnsig", "2.2>2.3@3", id="nnsig-upstream-lost-running"),
    pytest.param("nnsin", "2.1>2.3", id="nnsin-bypass"),
    pytest.param("nnsig", "2.3>2.1", id="nnsig-bypass-back"),
    # the upstream module's READY goes unheard: no states follow it, so the slave is deaf on
    # that wire and its polls no longer count as hearing upstream; it paces as after a cut
    pytest.param("nnsin", "2.3>2.2", id="nnsin-downstream-lost-power-up"),
    pytest.param("nnsig", "2.3>2.2", id="nnsig-downstream-lost-power-up"),
    pytest.param("nnsin", "0.1>0.0@2.5", id="nnsin-downstream-lost-running-lead"),
    pytest.param("nnsig", "2.3>2.2@3", id="nnsig-downstream-lost-running"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("model", "one_way"), NN_CASES)
def test_an_nn_one_way_wire(traced_build, model: str, one_way: str) -> None:
    report = _run(traced_build(model), one_way)
    assert report.ok, report.check.first_mismatch or report.result.stalled


def test_the_cut_option_parses_one_way_wires(traced_build, cli) -> None:
    build = str(traced_build("ca1d"))
    bad = cli("twin", build, "--no-physics", "-T", "1", "--cut", "0.1>0.3")
    assert bad.code == 2 and "no wire joins" in bad.err
    bad = cli("twin", build, "--no-physics", "-T", "1", "--cut", "0.1>>0.2")
    assert bad.code == 2 and "A>B" in bad.err
    from bstool.commands.twin import _parse_cut

    assert _parse_cut("0.1>0.2@3.5", 5, 6) == (ModuleId(0, 1), ModuleId(0, 2), 3.5, True)
    assert _parse_cut("0.1-0.2", 5, 6) == (ModuleId(0, 1), ModuleId(0, 2), None, False)
    with pytest.raises(InputError):
        _parse_cut("0.1>0.2@x", 5, 6)


def test_clocks_beyond_the_uart_tolerance_are_named(traced_build) -> None:
    """``--clock-spread 0.05``: neighbours drawn more than 4 % apart make a wire one-way; the
    twin names the pair and the ratio (it used to compare with the healthy reference without a
    word) and compares that wire as one-way from power-up."""
    build = load_build(traced_build("ca1d"))
    perturb = Perturbation(clock_spread=0.05, seed=3)
    options = TwinOptions(transitions=4, physics=False, perturb=perturb, seed=3)
    report = run_twin(build, options)
    from hil_mock.robot import RobotTwin

    twin = RobotTwin(build, physics=False, perturb=perturb)
    pairs = clock_mismatches(twin)
    assert pairs, "seed 3 draws at least one pair of neighbours more than 4 % apart"
    (a, b), ratio = next(iter(pairs.items()))
    assert abs(ratio - 1) > 0.04
    notes = " ".join(report.check.notes)
    assert f"wire {a.label}-{b.label}" in notes and "tolerance" in notes
