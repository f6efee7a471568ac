"""bench/targets_frontier.py: issue 29 §5's three ratios and how many targets a gait meets, on
which docs/results.md's "Every NN gait against issue 29's targets" rests."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _frontier() -> ModuleType:
    path = ROOT / "bench" / "targets_frontier.py"
    spec = importlib.util.spec_from_file_location("targets_frontier", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _figures(nominal: float, mean: float, p10: float) -> dict[str, float]:
    return {"nominal": nominal, "mean": mean, "p10": p10, "worst": p10 / 2}


def _summary() -> dict[str, object]:
    return {
        "nnsig": {
            "runs": {
                "shipped": _figures(0.30, 0.14, 0.01),
                "all-three": _figures(0.27, 0.20, 0.15),  # 0.9x, 1.43x, 56 %
                "tail-only": _figures(0.12, 0.11, 0.07),  # 0.4x, 0.79x, 58 %
                "nominal-and-mean": _figures(0.40, 0.19, 0.06),  # 1.33x, 1.36x, 15 %
                "shipped-now": _figures(0.27, 0.20, 0.15),  # all-three under another name
            },
            "verdict": {},
        }
    }


def test_ratios_are_against_the_gait_shipped_before_and_the_gaits_own_nominal() -> None:
    tf = _frontier()
    table, copies = tf.table(_summary())
    rows = table["nnsig"]
    assert "shipped" not in rows
    assert set(rows) == {"all-three", "tail-only", "nominal-and-mean"}
    assert copies == ["nnsig: shipped-now is all-three (the same figures), counted once"]
    r = rows["all-three"]
    assert r["mean"] == pytest.approx(0.20 / 0.14)
    assert r["p10"] == pytest.approx(0.15 / 0.27)
    assert r["nominal"] == pytest.approx(0.27 / 0.30)
    assert tf.met(r) == [True, True, True]
    assert tf.met(rows["tail-only"]) == [False, True, False]
    assert tf.met(rows["nominal-and-mean"]) == [True, False, True]


def test_a_gait_that_does_not_move_has_no_tail_fraction() -> None:
    tf = _frontier()
    r = tf.ratios(_figures(0.0, 0.0, 0.0), _figures(0.3, 0.14, 0.01))
    assert r["p10"] == 0.0 and tf.met(r) == [False, False, False]
    still = tf.ratios(_figures(0.3, 0.2, 0.1), _figures(0.0, 0.0, 0.0))  # a baseline that stood
    assert still["mean"] == 0.0 and still["nominal"] == 0.0


def test_a_summary_without_the_baseline_is_refused() -> None:
    tf = _frontier()
    with pytest.raises(SystemExit, match="no 'shipped' gait"):
        tf.table({"nnsin": {"runs": {"a": _figures(0.3, 0.2, 0.1)}}})
    with pytest.raises(SystemExit, match="no gait besides 'shipped'"):
        tf.table({"nnsin": {"runs": {"shipped": _figures(0.3, 0.2, 0.1)}}})


def test_the_command_prints_the_counts_and_writes_the_plot(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    tf = _frontier()
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps(_summary()))
    plot = tmp_path / "frontier.png"
    monkeypatch.setattr("sys.argv", ["targets_frontier", str(summary), "--plot", str(plot)])
    tf.main()
    out = capsys.readouterr().out
    assert "all-three" in out and "3 of 3" in out
    assert "the most targets any meets: 3 of 3" in out
    assert "3 gaits" in out and "shipped-now is all-three" in out
    assert plot.read_bytes().startswith(b"\x89PNG")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frontier.png", "summary.json"]


def test_the_plot_is_written_in_the_format_its_name_says(tmp_path: Path) -> None:
    tf = _frontier()
    table, _ = tf.table(_summary())
    tf.plot(table, tmp_path / "frontier.pdf")
    assert (tmp_path / "frontier.pdf").read_bytes().startswith(b"%PDF")
