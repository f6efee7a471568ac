"""A twin as unkind as real stamps (issue 12 §1): ``--timing-scale``, ``--timing-spread``,
``--clock-spread``, ``--start-spread``, ``--reset``, ``--item-time`` and the UART tolerance.

Small runs without physics. Figures for every model and case: ``python
bench/twin_robustness.py`` (docs/twin.md, "Perturbations").
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import traced_controller

from bstool.cli import main
from bstool.controllers import load_controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.tokenizer import tokenize_source
from hil_mock.perturb import Perturbation, Reset, draw, parse_reset
from hil_mock.robot import RobotTwin, TwinResult, load_build
from hil_mock.stamp import RecordingIO, SimpleEeprom, Stamp, Status, timing
from hil_mock.stamp.clock import UART_TOLERANCE, StampClock, frame_received

T = 6


@pytest.fixture(scope="module")
def build(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ca1d") / "build"
    assert main(["compile", str(traced_controller("ca1d")), "-o", str(out), "-q"]) == 0
    return out


def _twin_json(build: Path, capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    capsys.readouterr()
    try:  # the command exits 1 when the states differ from the reference
        main(["twin", str(build), "-T", "2", "--no-physics", "--json", *args])
    except SystemExit as exc:
        assert exc.code == 1
    return json.loads(capsys.readouterr().out)


def _same(a: TwinResult, b: TwinResult) -> bool:
    return (
        a.states == b.states
        and a.periods == b.periods
        and a.servo_gaps == b.servo_gaps
        and a.virtual_seconds == b.virtual_seconds
        and a.instructions == b.instructions
    )


# ---- options ----------------------------------------------------------------------------------
def test_every_option_parses_and_is_reported_in_json(
    build: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _twin_json(build, capsys, "--timing-scale", "1.5", "--timing-spread", "0.1",
                     "--clock-spread", "0.01", "--start-spread", "0.2", "--item-time", "40",
                     "--reset", "0.2@0.6+0.25", "--seed", "5")  # fmt: skip
    p = out["perturbations"]
    assert (p["timing_scale"], p["timing_spread"], p["clock_spread"]) == (1.5, 0.1, 0.01)
    assert (p["start_spread_s"], p["item_time_us"], p["seed"]) == (0.2, 40.0, 5)
    assert p["resets"] == ["0.2@0.6+0.25"]
    assert p["uart_tolerance"] == UART_TOLERANCE
    assert len(p["modules"]) == 30
    for d in p["modules"].values():
        assert 0.9 <= d["timing"] <= 1.1 and 0.99 <= d["resonator"] <= 1.01
        assert 0.0 <= d["start_s"] <= 0.2
        assert d["speed"] == pytest.approx(1.5 * d["timing"] * d["resonator"])
    assert p["power"] == [
        {"module": "0.2", "reset": "0.2@0.6+0.25", "off_s": [0.6], "booted_s": [0.85]}
    ]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--timing-scale", "0.4"], "--timing-scale must be in 0.5..3"),
        (["--timing-scale", "3.5"], "--timing-scale must be in 0.5..3"),
        (["--timing-spread", "-0.1"], "--timing-spread must be in 0..0.5"),
        (["--clock-spread", "0.2"], "--clock-spread must be in 0..0.1"),
        (["--clock-spread", "nan"], "--clock-spread must be in 0..0.1"),
        (["--start-spread", "61"], "--start-spread must be in 0..60"),
        (["--item-time", "-1"], "--item-time must be in 0..2000"),
        (["--reset", "0.0@3"], "expected L.M@T+OFF"),
        (["--reset", "0.0@3+0"], "must stay off for more than 0"),
        (["--reset", "7.0@3+1"], "--reset 7.0@3+1: unknown module 7.0"),
        (["--reset", "0.1@3+1", "--fail", "0.1"], "is failed"),
        (["--reset", "0.1@3+1", "--reset", "0.1@3.5+1"], "overlaps"),
    ],
)
def test_bad_values_are_input_errors(
    build: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["twin", str(build), "-T", "1", "--no-physics", "-q", *args]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


def test_reset_syntax() -> None:
    assert parse_reset("2.3@4.5+0.25") == Reset("2.3", 4.5, 0.25)
    assert str(parse_reset(" 0.0 @ 3 + .5 ")) == "0.0@3+0.5"
    with pytest.raises(InputError):
        parse_reset("2.3@4.5")


def test_draws_are_deterministic_for_a_seed_and_independent_of_other_options() -> None:
    mods = [ModuleId(i, j) for i in range(5) for j in range(6)]
    a = draw(Perturbation(timing_spread=0.2, clock_spread=0.02, seed=3), mods)
    assert a == draw(Perturbation(timing_spread=0.2, clock_spread=0.02, seed=3), mods)
    assert a != draw(Perturbation(timing_spread=0.2, clock_spread=0.02, seed=4), mods)
    b = draw(Perturbation(timing_spread=0.2, start_spread=2.0, seed=3), mods)
    assert [d.timing for d in a.values()] == [d.timing for d in b.values()]
    assert all(d.resonator == 1.0 for d in b.values())


def test_a_perturbed_run_is_deterministic(build: Path) -> None:
    p = Perturbation(timing_spread=0.2, clock_spread=0.01, start_spread=0.5, seed=9)
    b = load_build(build)
    one = RobotTwin(b, physics=False, perturb=p).run(T)
    two = RobotTwin(b, physics=False, perturb=p).run(T)
    assert _same(one, two)


def test_neutral_values_leave_the_twin_bit_identical(build: Path) -> None:
    """Checked by hand against the commit before this change (JSON of 5 models × plain, 1 %
    noise and --die runs, byte for byte); here: the neutral options are no-ops."""
    b = load_build(build)
    plain = RobotTwin(b, physics=False, noise=0.01, seed=2).run(T)
    neutral = Perturbation(timing_scale=1.0, timing_spread=0.0, clock_spread=0.0,
                           start_spread=0.0, seed=2)  # fmt: skip
    assert neutral.neutral
    again = RobotTwin(b, physics=False, noise=0.01, seed=2, perturb=neutral).run(T)
    assert _same(plain, again)


# ---- where today's protocol survives ------------------------------------------------------------
@pytest.mark.parametrize(
    "p",
    [
        Perturbation(timing_scale=0.5),
        Perturbation(timing_scale=2.0),
        Perturbation(timing_spread=0.2, seed=1),
        Perturbation(clock_spread=0.02, seed=1),
    ],
    ids=["scale0.5", "scale2", "spread20", "clock2"],
)
def test_ca1d_stays_exact_under_timing_and_clock_perturbations(
    build: Path, p: Perturbation
) -> None:
    b = load_build(build)
    result = RobotTwin(b, physics=False, perturb=p).run(T)
    assert result.stalled == []
    want = load_controller(build / "controller.json").states(T)
    np.testing.assert_array_equal(result.state_array(b.legs, b.modules, T), want)


@pytest.mark.parametrize(
    "p",
    [
        Perturbation(timing_spread=0.2, seed=1),
        Perturbation(clock_spread=0.02, item_time_us=50.0, seed=1),
    ],
    ids=["spread20", "clock2-item50"],
)
def test_nnsin_stays_exact_under_spreads(
    tmp_path_factory: pytest.TempPathFactory, p: Perturbation
) -> None:
    out = tmp_path_factory.getbasetemp() / "nnsin-build"
    if not out.is_dir():
        assert main(["compile", str(traced_controller("nnsin")), "-o", str(out), "-q"]) == 0
    b = load_build(out)
    result = RobotTwin(b, physics=False, perturb=p).run(T)
    assert result.stalled == []
    want = load_controller(out / "controller.json").states(T)
    np.testing.assert_array_equal(result.state_array(b.legs, b.modules, T), want)


# ---- start-up and resets ----------------------------------------------------------------------
def test_a_module_started_late_starts_its_program_late(build: Path) -> None:
    p = Perturbation(start_spread=1.0, seed=4)
    twin = RobotTwin(load_build(build), physics=False, perturb=p)
    twin.run(1, timeout_s=1.2)
    starts = {m: d.start_s for m, d in twin.perturb.draws.items()}
    assert max(starts.values()) - min(starts.values()) > 0.5
    wires = load_build(build).manifest.links
    for mid, rec in twin.records.items():
        # a program joins first: it pulses once every neighbour has answered (protocol/link.md
        # §4.3), so not before its own start nor long after its latest neighbour's
        peers = [
            w.slave if w.master == mid else w.master for w in wires if mid in (w.master, w.slave)
        ]
        first_pulse = rec.times_ns[0] / 1e9
        assert starts[mid] <= first_pulse < max(starts[m] for m in [mid, *peers]) + 0.3, mid


def test_a_reset_module_loses_its_ram_and_boots_again_from_eeprom(build: Path) -> None:
    mid = ModuleId(0, 3)
    b = load_build(build)
    twin = RobotTwin(b, physics=False, perturb=Perturbation(resets=(Reset("0.3", 4.0, 0.3),)))
    twin.run(20, timeout_s=4.1)  # off now: not scheduled, servo limp
    assert mid not in twin.stamps and twin.servos[mid].limp
    stamp = twin.ran[mid]
    tn_of = twin._readers[mid][1]
    assert len(twin.records[mid].times_ns) > 2  # it has moved on: RAM holds its transition
    assert tn_of(stamp) == (len(twin.records[mid].times_ns) - 1) & 7
    stamp.memory.scratch[5] = 0xA5
    twin.run(20, timeout_s=4.3005)  # just booted
    assert mid in twin.stamps and stamp.memory.scratch[5] == 0 and tn_of(stamp) == 0
    assert twin.perturb.offs[mid] == [4.0] and twin.perturb.boots[mid] == [4.3]
    twin.run(20, timeout_s=4.4)
    announcement = f"bstool L0.M3 {b.manifest.controller.hash8}\r".encode()
    assert bytes(stamp.debug).count(announcement) == 2  # re-announced: the program from the top


# ---- the stamp's own clock ----------------------------------------------------------------------
PROGRAM = """\
' {$STAMP BS2sx}
' {$PBASIC 2.5}
b VAR Byte
PULSOUT 12, 1000
PAUSE 10
SEROUT 1, 240, [65, 66]
SERIN 2, 240, 50, done, [b]
done:
END
"""


def _timed(clock: StampClock) -> tuple[Stamp, RecordingIO]:
    image = tokenize_source(PROGRAM, "clock.bsx").slots[0].eeprom
    io = RecordingIO()
    stamp = Stamp(SimpleEeprom([image]), io=io, clock=clock)
    assert stamp.run(1.0) is Status.WAITING
    return stamp, io


def test_a_resonator_factor_scales_pause_pulsout_serin_timeout_and_bit_rate() -> None:
    f = 1.013
    n_stamp, n_io = _timed(StampClock())
    s_stamp, s_io = _timed(StampClock(resonator=f))  # instructions kept nominal (speed 1)
    (_, n_p0, n_width, _), (_, s_p0, s_width, _) = n_io.pulses[0], s_io.pulses[0]
    assert n_width == 1000 * 800 and s_width == round(1000 * 800 * f)
    # pulse end -> first byte: the same statements plus PAUSE 10
    n_gap = n_io.serial[0][2] - (n_p0 + n_width)
    s_gap = s_io.serial[0][2] - (s_p0 + s_width)
    assert s_gap - n_gap == round(10_000_000 * f) - 10_000_000
    byte = timing.byte_ns(240)
    assert n_io.serial[1][2] - n_io.serial[0][2] == byte
    assert s_io.serial[1][2] - s_io.serial[0][2] == round(byte * f)
    assert s_stamp.clock.bit_ns(240) == pytest.approx(byte / 10 * f)
    for stamp, k in ((n_stamp, 1.0), (s_stamp, f)):
        w = stamp.wait
        assert w is not None and w.deadline is not None
        assert w.deadline - w.since == round(50 * 400_000 * k)


def test_a_speed_factor_scales_every_instruction() -> None:
    _, n_io = _timed(StampClock())
    _, s_io = _timed(StampClock(speed=2.0))
    assert s_io.pulses[0][1] == 2 * n_io.pulses[0][1]  # the statements before the pulse
    assert s_io.pulses[0][2] == n_io.pulses[0][2]  # the pulse is the resonator's


def test_uart_tolerance_accepts_a_frame_within_it_and_rejects_one_beyond() -> None:
    bit = timing.byte_ns(240) / 10
    assert frame_received(bit, bit * 1.039) and frame_received(bit, bit / 1.039)
    assert not frame_received(bit, bit * 1.041) and not frame_received(bit, bit * 0.959)
    for ratio, taken in ((1.03, True), (0.97, True), (1.05, False), (0.95, False)):
        stamp, _ = _timed(StampClock())
        w = stamp.wait
        assert w is not None
        assert stamp.deliver_byte(2, 7, w.since, 240, bit * ratio) is taken
        assert stamp.rx_mismatched == (0 if taken else 1)
        assert stamp.status is (Status.RUNNING if taken else Status.WAITING)


def test_stamp_serial_timing_spaces_bytes_and_rearms_after_the_stop_sample() -> None:
    stamp, io = _timed(StampClock(item_ns=60_000))
    byte = timing.byte_ns(240)
    assert io.serial[1][2] - io.serial[0][2] == byte + 60_000  # SEROUT evaluates item 2
    w = stamp.wait
    assert w is not None
    start = w.since + 1000
    assert stamp.deliver_byte(2, 7, start, 240)
    # the stop bit is sampled 9.5 bit times after the start edge; the next item 60 us later
    assert stamp.t == start + round(9.5 * byte / 10) + 60_000


# ---- python -m hil_mock serve ----------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--timing-scale", "5"], "--timing-scale must be in 0.5..3"),
        (["--reset", "0.0@1+1"], "--reset needs a robot run"),
    ],
)
def test_serve_rejects_bad_values_without_a_traceback(args: list[str], message: str) -> None:
    from click.testing import CliRunner

    from hil_mock.__main__ import main as hil_main

    result = CliRunner().invoke(hil_main, ["serve", "--modules", "1", *args])
    assert result.exit_code == 2
    assert message in result.output
    assert isinstance(result.exception, SystemExit)


def test_serve_gives_each_preview_stamp_its_clock_and_start() -> None:
    from hil_mock.perturb import perturb_runner, serve_draws
    from hil_mock.runners import InterpreterRunner

    p = Perturbation(timing_scale=2.0, clock_spread=0.01, start_spread=0.3, seed=1)
    d = serve_draws(p, [ModuleId(0, 0)])[ModuleId(0, 0)]
    runner = InterpreterRunner()
    perturb_runner(runner, p, d)
    assert runner.clock is not None and runner.start_s == d.start_s
    assert runner.clock.resonator == d.resonator
    assert runner.clock.speed == pytest.approx(2.0 * d.resonator)
