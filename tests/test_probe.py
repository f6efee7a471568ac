"""bstool probe (bstool/probe): the measurement program, the robust fit, the marker reader,
its errors, and end to end over a pty against ``python -m hil_mock serve --timing real``."""

from __future__ import annotations

import json
import os
import pty
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import traced_controller
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool import timingfile as tf
from bstool.errors import DeviceError
from bstool.probe import fit, measure
from bstool.probe import program as P
from hil_mock.realtime import debug_bytes
from hil_mock.stamp.clock import StampClock
from hil_mock.stamp.interpreter import Stamp

QUICK = P.build(quick=True)
FULL = P.build(repeats=5)


def _stamp(program: P.ProbeProgram, clock: StampClock | None = None) -> Stamp:
    return Stamp([program.image.eeprom] + [bytes(2048)] * 7, clock=clock)


def virtual_times(
    program: P.ProbeProgram, clock: StampClock | None = None
) -> dict[tuple[int, int], float]:
    """Marker arrival times (the byte's end, s) of ``program`` run on the twin's interpreter."""
    sent = debug_bytes(_stamp(program, clock), 600 * 10**9)
    header = P.HEADER.encode() + b"\r"
    assert bytes(b for b, _, _ in sent[: len(header)]) == header
    marks = sent[len(header) :]
    per = program.markers_per_repeat
    assert len(marks) == program.repeats * per
    times = {}
    for i, (value, _start, end) in enumerate(marks):
        r, m = divmod(i, per)
        assert value == (m + 1 if m + 1 < per else P.END_MARKER)
        times[(r, m + 1)] = end / 1e9
    return times


# ---- the program --------------------------------------------------------------------------
def test_program_fits_one_slot_and_knows_its_bits() -> None:
    for program in (QUICK, FULL):
        assert program.image.program_bytes < 2048
        assert set(program.info) == {k.name for k in P.kinds()}
        assert len(program.segments) == 2 * len(P.kinds())
    info = QUICK.info
    assert info["empty"].statements == 1 and info["assign"].statements == 2
    assert info["assign"].bits - info["empty"].bits == 44  # x = x + 1 (docs/twin.md)
    assert info["pause_1"].bits == info["pause_20"].bits  # the count is in a variable
    assert QUICK.expected_seconds() < 8 and FULL.expected_seconds() < 35


# ---- the fit ------------------------------------------------------------------------------
@pytest.mark.parametrize(("speed", "resonator"), [(1.0, 1.0), (1.8, 1.0), (0.7, 1.01)])
def test_fit_recovers_the_twins_timing(speed: float, resonator: float) -> None:
    times = virtual_times(QUICK, StampClock(speed=speed, resonator=resonator))
    model = fit.fit(QUICK, fit.intervals(QUICK, times))
    c = speed  # StampClock.speed is the whole instruction factor (perturb folds the resonator in)
    assert model.instruction_time_ratio.value == pytest.approx(c, rel=1e-3)
    assert model.base_us.value == pytest.approx(20 * c, rel=0.01)
    assert model.per_bit_us.value == pytest.approx(2 * c, rel=0.01)
    assert model.pause_unit_ms.value == pytest.approx(resonator, rel=1e-3)
    assert model.pulsout_unit_us.value == pytest.approx(0.8 * resonator, rel=1e-3)
    assert model.serin_unit_ms.value == pytest.approx(0.4 * resonator, rel=1e-3)
    assert model.serout_item_us.value == pytest.approx(1040 * resonator, rel=0.01)
    assert model.run_us.sd is None  # not measured


def test_robust_slope() -> None:
    assert fit.robust_slope([1.0, 1.0, 1.0]) == (1.0, 0.0)
    value, sd = fit.robust_slope([1.0, 1.1, 0.9, 50.0, 1.0])
    assert value == 1.0 and 0 < sd < 0.1


_EXACT = {s: virtual_times(FULL, StampClock(speed=s)) for s in (1.0, 1.8)}


@settings(max_examples=25, deadline=None)
@given(
    speed=st.sampled_from(sorted(_EXACT)),
    jitter_ms=st.floats(0.0, 0.5),
    outliers=st.lists(
        st.tuples(st.integers(0, 4), st.integers(1, len(FULL.segments) + 1), st.floats(0, 0.2)),
        max_size=2,  # floor((R - 1) / 2) markers of R = 5 repeats, anywhere, any delay
    ),
    seed=st.integers(0, 2**32 - 1),
)
def test_fit_is_robust_to_jitter_and_late_markers(
    speed: float, jitter_ms: float, outliers: list[tuple[int, int, float]], seed: int
) -> None:
    rng = np.random.default_rng(seed)
    times = {k: t + abs(rng.normal(0, jitter_ms / 1000)) for k, t in _EXACT[speed].items()}
    for r, m, delay in outliers:
        times[(r, m)] += delay  # a USB latency spike: that marker is read late
    model = fit.fit(FULL, fit.intervals(FULL, times))
    assert model.instruction_time_ratio.value == pytest.approx(speed, rel=0.01)
    assert model.pause_unit_ms.value == pytest.approx(1.0, rel=0.01)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fit_through_a_usb_adapters_latency_timer(seed: int) -> None:
    """An FTDI adapter holds received bytes up to its latency timer (16 ms by default): every
    marker late by 0-16 ms. The full probe still gives the ratio within 2 % (rms ~0.4 %), and
    its standard error says so."""
    rng = np.random.default_rng(seed)
    times = {k: t + rng.uniform(0, 0.016) for k, t in _EXACT[1.8].items()}
    r = fit.fit(FULL, fit.intervals(FULL, times)).instruction_time_ratio
    assert r.value == pytest.approx(1.8, rel=0.02)
    assert r.sd is not None and 0.001 < r.sd / 1.8 < 0.02


def test_fit_drops_intervals_of_lost_markers() -> None:
    times = dict(_EXACT[1.8])
    del times[(0, 3)], times[(2, 5)]
    model = fit.fit(FULL, fit.intervals(FULL, times))
    assert model.instruction_time_ratio.value == pytest.approx(1.8, rel=1e-3)
    for r in range(FULL.repeats):  # every marker of one kind lost: a clear error
        times.pop((r, 2), None)
    with pytest.raises(DeviceError, match="no complete measurement of the empty loops"):
        fit.fit(FULL, fit.intervals(FULL, times))


# ---- the marker reader --------------------------------------------------------------------
class _Script:
    """A serial port that returns scripted bytes, one per read; a clock of their times."""

    def __init__(self, data: list[tuple[int, float]]) -> None:
        self.data = data
        self.now = 0.0
        self.timeout = 0.0

    def read(self, n: int) -> bytes:
        if not self.data:
            return b""
        value, self.now = self.data.pop(0)
        return bytes([value])

    def clock(self) -> float:
        return self.now


def _sequence(program: P.ProbeProgram) -> list[int]:
    per = program.markers_per_repeat
    return [
        m + 1 if m + 1 < per else P.END_MARKER for _ in range(program.repeats) for m in range(per)
    ]


def test_read_markers_skips_garbage_and_resynchronises() -> None:
    seq = _sequence(QUICK)
    per = QUICK.markers_per_repeat
    data = [(v, float(i)) for i, v in enumerate(seq)]
    del data[per + 4]  # marker 5 of repeat 1 lost
    data.insert(3, (0x7F, 2.5))  # a garbled byte
    del data[2 * per - 1]  # the end marker of repeat 1 (shifted by the two edits) lost
    ser = _Script(data)
    times, lost = measure.read_markers(ser, QUICK, port="fake", clock=ser.clock)  # type: ignore[arg-type]
    assert lost == 3
    assert times[(0, 1)] == 0.0 and times[(0, 3)] == 2.0 and times[(0, 4)] == 3.0
    assert (1, 5) not in times and times[(1, 6)] == float(per + 5)
    assert (1, per) not in times and times[(2, 1)] == float(2 * per)
    assert len(times) == len(seq) - 2


def test_read_markers_silence_is_a_device_error() -> None:
    ser = _Script([(1, 0.0), (2, 1.0)])
    with pytest.raises(DeviceError, match="stopped sending after 2 of") as err:
        measure.read_markers(ser, QUICK, port="fake", clock=ser.clock)  # type: ignore[arg-type]
    assert err.value.hint


# ---- errors through the CLI ----------------------------------------------------------------
def test_wrong_port(cli: Callable[..., Any], tmp_path: Path) -> None:
    run = cli("probe", "--port", str(tmp_path / "ttyUSB9"), "-o", str(tmp_path / "t.json"))
    assert run.code != 0 and "does not exist" in run.err and "Traceback" not in run.err
    assert not (tmp_path / "t.json").exists()


@pytest.fixture
def fast_flash(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BSTOOL_FLASH_FAST", "1")


@pytest.fixture
def silent_pty() -> Iterator[str]:
    """A pty nothing answers on (a cable with no stamp)."""
    master, slave = pty.openpty()
    import tty

    tty.setraw(slave)
    yield os.ttyname(slave)
    os.close(master)
    os.close(slave)


def test_no_answer(
    cli: Callable[..., Any], silent_pty: str, fast_flash: None, tmp_path: Path
) -> None:
    run = cli("probe", "--port", silent_pty, "-q", "-o", str(tmp_path / "t.json"))
    assert run.code != 0 and "nothing echoed" in run.err and "hint" in run.err.lower()
    assert "Traceback" not in run.err


def test_stamp_that_does_not_run_the_program(
    cli: Callable[..., Any], fast_flash: None, tmp_path: Path
) -> None:
    from hil_mock.eeprom import Eeprom
    from hil_mock.progdevice import ProgrammingDevice
    from hil_mock.ptyendpoint import PtyEndpoint
    from hil_mock.runners import ScanRunner

    with PtyEndpoint(ProgrammingDevice(Eeprom(), runner=ScanRunner())) as ep:
        run = cli("probe", "--port", ep.path, "-q", "-o", str(tmp_path / "t.json"))
    err = run.err
    assert run.code != 0 and "took the probe program but did not start it" in err
    assert "Traceback" not in err


# ---- compile --timing, twin --timing, the twin's model ---------------------------------------
def _ratio_file(tmp_path: Path, ratio: float) -> Path:
    c = tf.DEFAULT
    model = replace(
        c,
        base_us=tf.Coefficient(c.base_us.value * ratio, 0.1),
        per_bit_us=tf.Coefficient(c.per_bit_us.value * ratio, 0.01),
        run_us=tf.Coefficient(c.run_us.value * ratio),
        instruction_time_ratio=tf.Coefficient(ratio, 0.001),
        source="test",
    )
    path = tmp_path / f"timing-{ratio}.json"
    tf.dump(model, path)
    return path


def test_compile_timing_changes_the_estimates(cli: Callable[..., Any], tmp_path: Path) -> None:
    ctrl = str(traced_controller("ca1d"))
    slow = _ratio_file(tmp_path, 1.8)
    assert cli("compile", ctrl, "-o", str(tmp_path / "a"), "-q").code == 0
    assert cli("compile", ctrl, "-o", str(tmp_path / "b"), "-q", "--timing", str(slow)).code == 0
    a = json.loads((tmp_path / "a" / "manifest.json").read_text())["modules"]
    b = json.loads((tmp_path / "b" / "manifest.json").read_text())["modules"]
    for ma, mb in zip(a, b, strict=True):
        assert mb["timing"]["nominal_transition_s"] > ma["timing"]["nominal_transition_s"]
        assert mb["timing"]["longest_servo_gap_s"] > ma["timing"]["longest_servo_gap_s"]
    from bstool.compile import timing as ct

    assert ct.STMT_MS == 0.1 and ct.DEFAULT.model == tf.DEFAULT  # a value: nothing to restore
    assert ct.CompileTiming(tf.load(slow)).stmt_ms == pytest.approx(0.18)
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    run = cli("compile", ctrl, "-o", str(tmp_path / "c"), "--timing", str(bad))
    assert run.code != 0 and "not a timing file" in run.err


def test_the_twin_takes_the_file(tmp_path: Path) -> None:
    """The file's model is a value of the stamp's clock, not a process-wide setting."""
    from hil_mock import measured
    from hil_mock.stamp import timing as ht

    want = virtual_times(QUICK, StampClock(speed=1.8))
    model = measured.load(_ratio_file(tmp_path, 1.8))
    assert model is not None
    got = virtual_times(QUICK, StampClock(model=model))
    assert got == pytest.approx(want, abs=1e-6)
    assert (ht.BASE_NS, ht.PER_BIT_NS) == (20_000, 2_000)
    assert ht.of(None) == ht.ESTIMATE == ht.of(tf.DEFAULT)
    assert virtual_times(QUICK) == pytest.approx(virtual_times(QUICK, StampClock()))
    assert measured.load(None) is None


def test_twin_timing_runs(
    cli: Callable[..., Any], traced_build: Callable[..., Path], tmp_path: Path
) -> None:
    build = traced_build("ca1d")
    f = _ratio_file(tmp_path, 1.2)
    run = cli("twin", str(build), "-T", "3", "--no-physics", "--json", "-q", "--timing", str(f))
    assert run.code in (0, 1), run.err
    assert json.loads(run.out)["instructions"] > 0
    from hil_mock.stamp import timing as ht

    assert ht.BASE_NS == 20_000  # restored after the run


def test_serve_rejects_a_bad_timing_model(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from hil_mock.__main__ import main as hil_main

    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "x"}')
    result = CliRunner().invoke(hil_main, ["serve", "--timing-model", str(bad)])
    assert result.exit_code == 2 and "not a timing file" in result.output


# ---- end to end over a pty with real 9600-baud pacing ---------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize(("scale", "file_ratio"), [(1.8, None), (1.0, None), (1.0, 1.5)])
def test_probe_measures_the_served_twin(
    scale: float, file_ratio: float | None, tmp_path: Path
) -> None:
    """`python -m hil_mock serve --timing-scale F --timing real` is measured as F within 3 %;
    served with a timing file (--timing-model) as the file's ratio. Five repeats (not --quick's
    3): the median then survives two repeats spoiled by a loaded machine delaying the twin."""
    model_args = []
    if file_ratio is not None:
        model_args = ["--timing-model", str(_ratio_file(tmp_path, file_ratio))]
        scale = file_ratio
    serve = subprocess.Popen(
        [sys.executable, "-m", "hil_mock", "serve", "--timing", "real",
         "--timing-scale", str(1.0 if file_ratio else scale), *model_args],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )  # fmt: skip
    try:
        assert serve.stdout is not None
        _label, port = serve.stdout.readline().split()
        out = tmp_path / "stamp-timing.json"
        done = subprocess.run(
            [sys.executable, "-m", "bstool", "probe", "--port", port, "--quick", "--repeats", "5",
             "--json", "-o", str(out)],
            capture_output=True,
            text=True,
            timeout=60,
        )  # fmt: skip
    finally:
        serve.terminate()
        serve.wait(timeout=5)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    ratio = result["instruction_time_ratio"]
    print(f"scale {scale}: ratio {ratio:.4f} ± {result['instruction_time_ratio_sd']:.4f}")
    assert ratio == pytest.approx(scale, rel=0.03)
    model = tf.load(out)
    assert model.measured and model.instruction_time_ratio.value == ratio
    assert model.pause_unit_ms.value == pytest.approx(1.0, rel=0.03)


def test_an_in_process_twin_says_to_serve_one(cli: Callable[..., Any], tmp_path: Path) -> None:
    run = cli("probe", "--port", "bstwin://probe-preview", "--quick", "-q",
              "-o", str(tmp_path / "t.json"))  # fmt: skip
    assert run.code != 0 and "stopped sending after" in run.err
    assert "hil_mock serve --timing real" in run.err and "Traceback" not in run.err


def test_stamp_timed_simulator_takes_the_file(
    cli: Callable[..., Any], traced_build: Callable[..., Path], tmp_path: Path
) -> None:
    """`simulate --build B --timing F`: the schedule comes from stamps timed by the file (slower
    stamps: a longer measured period), and --timing without --build is refused."""
    build = traced_build("ca1d")
    ctrl = str(build / "controller.json")
    plain = cli("simulate", ctrl, "--build", str(build), "-T", "2", "--json", "-q")
    slow = cli("simulate", ctrl, "--build", str(build), "-T", "2", "--json", "-q",
               "--timing", str(_ratio_file(tmp_path, 1.8)))  # fmt: skip
    assert plain.code == 0 and slow.code == 0, slow.err
    assert json.loads(slow.out) != json.loads(plain.out)
    run = cli("simulate", ctrl, "--timing", str(_ratio_file(tmp_path, 1.8)))
    assert run.code == 2 and "--timing needs --build" in run.err
    # the schedule model (--stamp-timed) is fitted on stamps timed by the file as well
    model = cli("simulate", ctrl, "--stamp-timed", "-T", "4", "--json", "-q")
    model_slow = cli("simulate", ctrl, "--stamp-timed", "-T", "4", "--json", "-q",
                     "--timing", str(_ratio_file(tmp_path, 1.8)))  # fmt: skip
    assert model.code == 0 and model_slow.code == 0, model_slow.err
    assert json.loads(model_slow.out)["path"] != json.loads(model.out)["path"]
