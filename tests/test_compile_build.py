"""`bstool compile` end to end: outputs, determinism, errors, atomic output, tokenizer fit."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from bstool import buildfile
from bstool.cli import main
from bstool.compile import build, compile_controller, templates_dir
from bstool.compile.calibration import Servo, parse_calibration
from bstool.compile.timing import SERVO_HOLDS_MS
from bstool.errors import BuildError, InputError

GOLDEN = Path(__file__).parent / "golden" / "compile"
CA = GOLDEN / "ca2dsing.json"
NN = GOLDEN / "nnsig.json"


def _tree(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_cli_writes_every_module(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "build"
    assert main(["compile", str(CA), "-o", str(out), "--period", "0.5"]) == 0
    assert "compiled 30 modules" in capsys.readouterr().out
    man = json.loads((out / "manifest.json").read_text())
    assert man["format"] == "bstool.build/1" and len(man["modules"]) == 30
    assert [e["module"] for e in man["flash_order"]][:2] == ["0.0", "0.1"]
    assert man["flash_order"][0]["slots"] == [2, 1, 0]
    for entry in man["modules"]:
        main_bsx = (out / entry["entry"]).read_text()
        assert main_bsx.startswith("' {$STAMP BS2sx, rules1.bsx, rules2.bsx}\n' {$PBASIC 2.5}\n")
        boot = (out / entry["slots"][-1]["file"]).read_text()  # CA: power-up in the last slot
        assert f'DEBUG "bstool {entry["label"]} {man["controller"]["hash8"]}", CR' in boot
        assert entry["timing"]["longest_servo_gap_s"] < SERVO_HOLDS_MS / 1000  # docs/compile.md
        assert entry["ram_bytes"] <= 26
    assert (out / "WIRING.md").read_text().startswith("# Wiring for controller")


def test_output_is_deterministic(tmp_path: Path) -> None:
    for ctrl in (CA, NN):
        compile_controller(ctrl, tmp_path / "a", period=0.5)
        compile_controller(ctrl, tmp_path / "b", period=0.5)
        assert _tree(tmp_path / "a") == _tree(tmp_path / "b")


def test_module_option_and_rebuild_replaces(tmp_path: Path) -> None:
    out = tmp_path / "build"
    compile_controller(CA, out, period=0.5)
    (out / buildfile.PROGRESS_FILE).write_text("{}")  # flash's own file does not block it
    compile_controller(NN, out, period=0.5, modules=["2.3", "L0.M1"])
    assert sorted(p.name for p in (out / "modules").iterdir()) == ["L0.M1", "L2.M3"]
    assert not (out / buildfile.PROGRESS_FILE).exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folders


def test_a_rebuild_keeps_the_users_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file bstool did not write (the user's notes) is never deleted by a rebuild: it is
    refused with the file's name and a hint; --force replaces the folder whole (issue 28 §5)."""
    out = tmp_path / "build"
    compile_controller(CA, out, period=0.5)
    (out / "notes.txt").write_text("servo 2.3 is loose")
    (out / "modules" / "L0.M0" / "scope.csv").write_text("t,v")
    before = _tree(out)
    assert main(["compile", str(CA), "-o", str(out), "--period", "0.5", "-q"]) == 2
    err = capsys.readouterr().err
    assert "notes.txt" in err and "scope.csv" in err and "--force" in err
    assert _tree(out) == before
    assert main(["compile", str(CA), "-o", str(out), "--period", "0.5", "-q", "--force"]) == 0
    assert not (out / "notes.txt").exists() and buildfile.is_build(out)


def test_unknown_module(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="leg 7") as err:
        compile_controller(CA, tmp_path / "b", modules=["7.0"])
    assert err.value.hint and "4.5" in err.value.hint
    assert not (tmp_path / "b").exists()


def test_errors_leave_previous_build_untouched(tmp_path: Path) -> None:
    out = tmp_path / "build"
    compile_controller(CA, out, period=0.5)
    before = _tree(out)
    bad = tmp_path / "servos.json"
    bad.write_text('{"format": "bstool.servos/1", "modules": {"1.1": {"direction": 2}}}')
    assert main(["compile", str(NN), "-o", str(out), "--calibration", str(bad)]) == 5
    assert _tree(out) == before


def test_refuses_foreign_output_folder(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("precious")
    with pytest.raises(InputError, match="not empty"):
        compile_controller(CA, tmp_path, period=0.5)
    assert (tmp_path / "mine.txt").read_text() == "precious"


def test_a_foreign_manifest_json_does_not_make_a_build(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder is replaced only if its manifest.json has the bstool build format: a folder that
    merely holds a file called manifest.json (someone's web app, say) is left alone."""
    (tmp_path / "manifest.json").write_text('{"name": "my web app"}')
    (tmp_path / "index.html").write_text("precious")
    assert main(["compile", str(CA), "-o", str(tmp_path), "--period", "0.5", "-q"]) == 2
    err = capsys.readouterr().err
    assert "not a bstool build" in err and "-o" in err
    assert (tmp_path / "index.html").read_text() == "precious"
    assert (tmp_path / "manifest.json").read_text() == '{"name": "my web app"}'


def test_period_too_short(tmp_path: Path) -> None:
    with pytest.raises(BuildError, match="too short") as err:
        compile_controller(CA, tmp_path / "b", period=0.05)
    assert err.value.hint and "--period" in err.value.hint


@pytest.mark.parametrize(
    ("obj", "match"),
    [
        ([], "expected a JSON object"),
        ({"format": "x"}, "format"),
        ({"format": "bstool.servos/1", "default": {"centre_us": "a"}}, "expected a number"),
        ({"format": "bstool.servos/1", "default": {"wobble": 1}}, "unknown field"),
        ({"format": "bstool.servos/1", "default": {"min_us": 2000, "max_us": 1000}}, "min_us"),
        ({"format": "bstool.servos/1", "default": {"us_per_rad": 0}}, "> 0"),
        ({"format": "bstool.servos/1", "default": {"centre_us": 3000}}, "outside|min_us"),
        ({"format": "bstool.servos/1", "legs": 4}, "legs = 4"),
    ],
)
def test_invalid_calibration(obj: object, match: str) -> None:
    with pytest.raises(BuildError, match=match) as err:
        parse_calibration(obj, "servos.json", 5, 6)
    assert err.value.hint


def test_calibration_unknown_module() -> None:
    with pytest.raises(InputError, match="module 6"):
        parse_calibration({"format": "bstool.servos/1", "modules": {"0.6": {}}}, "s.json", 5, 6)


def test_calibration_overrides_one_module(tmp_path: Path) -> None:
    cal = tmp_path / "servos.json"
    cal.write_text(
        json.dumps(
            {
                "format": "bstool.servos/1",
                "default": {"centre_us": 1520},
                "modules": {"1.2": {"direction": -1, "max_us": 2000}},
            }
        )
    )
    compile_controller(NN, tmp_path / "b", calibration=cal, period=0.5, tokenize=False)
    man = json.loads((tmp_path / "b" / "manifest.json").read_text())
    servo = {m["module"]: m["servo"] for m in man["modules"]}
    assert servo["0.0"]["pulsout"][0] == round(
        (1520 - 1000 / (3.14159265358979 / 2) * 1.0471975511965976) / 0.8
    )
    flipped = servo["1.2"]["pulsout"]
    assert flipped == sorted(flipped, reverse=True) and max(flipped) == 2500  # 2000 µs limit
    assert servo["1.2"]["clipped_states"] == [0, 1, 2]  # above 2000 µs


def test_default_servo_covers_the_range() -> None:
    pulses = Servo().pulses()
    assert pulses[0] == 1042 and pulses[-1] == 2708  # 833 µs and 2167 µs: ±60°
    assert Servo().clipped() == []


def test_templates_dir_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    packaged = templates_dir()
    assert (packaged / "ca_main.bsx.j2").is_file()
    assert packaged.parent.name == "templates" or packaged.parts[-2:] == ("templates", "pbasic")
    monkeypatch.setenv("BSTOOL_TEMPLATES", str(tmp_path))
    with pytest.raises(BuildError, match="holds no PBASIC templates"):
        templates_dir()  # an override that holds no templates is a mistake, said at once
    shutil.copytree(packaged, tmp_path / "pbasic")
    monkeypatch.setenv("BSTOOL_TEMPLATES", str(tmp_path / "pbasic"))
    assert templates_dir() == tmp_path / "pbasic"


def test_missing_controller(tmp_path: Path) -> None:
    assert main(["compile", str(tmp_path / "nope.json"), "-o", str(tmp_path / "b")]) == 2
    assert not (tmp_path / "b").exists()


@pytest.mark.slow
@pytest.mark.parametrize("model", ["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"])
def test_every_program_tokenizes_and_fits(model: str, tmp_path: Path) -> None:
    res = compile_controller(GOLDEN / f"{model}.json", tmp_path / "b", period=0.5)
    assert res.tokenized
    for mod in res.modules:
        for sr in mod.slots:
            assert sr.program_bytes is not None and sr.data_bytes is not None
            assert sr.program_bytes + sr.data_bytes <= 2048
            assert sr.eeprom is not None and len(sr.eeprom) == 2048
            assert (
                tmp_path / "b" / "modules" / mod.plan.dirname / f"slot{sr.slot}.eeprom"
            ).is_file()
        assert mod.ram_bytes <= 26


@pytest.mark.slow
@pytest.mark.parametrize("model", ["nnsig", "nnsin"])
def test_the_largest_nn_programs_fit(model: str, tmp_path: Path) -> None:
    """Every upstream weight 1 and every R^0 15 (the initial states are constants in the
    program, and a larger constant takes more bits): module 3's NnTable and program are the
    largest any NN controller makes (2035 of 2048 bytes, protocol/link.md §4.6)."""
    import numpy as np

    from bstool.controllers import make_controller, save_controller

    ctrl = make_controller(model, np.full((5, 6), 15), weights=np.triu(np.ones((5, 6, 6), int), 1))
    save_controller(ctrl, tmp_path / "c.json")
    res = compile_controller(tmp_path / "c.json", tmp_path / "b")
    sizes = [sr.program_bytes + sr.data_bytes for mod in res.modules for sr in mod.slots]  # type: ignore[operator]
    assert max(sizes) <= 2048
    assert max(mod.ram_bytes for mod in res.modules) <= 26


def test_slot_that_does_not_fit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The tokenizer's error 124 becomes a BuildError naming the slot and the overflow."""
    from types import SimpleNamespace

    from bstool.errors import SourceError

    def fake_tokenize(sources: dict[str, str]) -> object:
        text = sources["rules1.bsx"]
        if text.count("$") > 100:  # the real table "does not fit"; the probe has one byte
            raise SourceError(
                "Data occupies same location as program",
                file="rules1.bsx",
                line=30,
                column=1,
                code=124,
            )
        image = SimpleNamespace(program_bytes=1100, data_bytes=1)
        return SimpleNamespace(slots={0: image, 1: image, 2: image})

    monkeypatch.setattr(build, "_tokenize_sources", fake_tokenize)
    with pytest.raises(
        BuildError, match=r"slot 1 \(rules1.bsx\) does not fit: 76 bytes over"
    ) as err:
        compile_controller(CA, tmp_path / "b", period=0.5, modules=["0.0"])
    assert err.value.hint and "RULE_SLOTS" in err.value.hint
    assert not (tmp_path / "b").exists()
    # the program and its DATA overlap though their sizes add up to the slot (its alignment):
    # no "0 bytes over"
    calls: list[int] = []

    def overlapping(sources: dict[str, str]) -> object:
        calls.append(1)
        if len(calls) == 1:  # the build; then the probe measures the program alone
            raise SourceError("Data occupies same location as program", file="main.bsx", code=124)
        return SimpleNamespace(slots={0: SimpleNamespace(program_bytes=2047, data_bytes=1)})

    monkeypatch.setattr(build, "_tokenize_sources", overlapping)
    with pytest.raises(BuildError, match="its program and DATA overlap in the 2048-byte slot"):
        compile_controller(CA, tmp_path / "b", period=0.5, modules=["0.0"])


def test_ram_overflow(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(build, "ram_estimate", lambda plan: 27)
    with pytest.raises(BuildError, match="27 bytes of RAM"):
        compile_controller(NN, tmp_path / "b", period=0.5, tokenize=False)


def test_build_holds_the_controller(tmp_path: Path) -> None:
    """build/controller.json is the compiled controller (same hash), listed in the manifest, so
    `bstool twin BUILD` compares with it by default."""
    from bstool.controllers import controller_hash, load_controller

    res = compile_controller(NN, tmp_path / "b", period=0.5, tokenize=False)
    man = json.loads((tmp_path / "b" / "manifest.json").read_text())
    copy = tmp_path / "b" / man["controller"]["copy"]
    assert man["controller"]["copy"] == "controller.json"
    assert (
        controller_hash(load_controller(copy)) == res.controller_hash == man["controller"]["hash"]
    )


def test_nn_manifest_lists_bypass_wires_and_timing(tmp_path: Path) -> None:
    compile_controller(NN, tmp_path / "b", period=0.5, tokenize=False)
    man = json.loads((tmp_path / "b" / "manifest.json").read_text())
    legs, modules = man["robot"]["legs"], man["robot"]["modules"]
    bypass = [w for w in man["links"] if w["bypass"]]
    assert len(bypass) == legs * (modules - 2)
    assert all((w["master_pin"], w["slave_pin"]) == (3, 2) for w in bypass)
    assert len(man["links"]) - len(bypass) == legs * (modules - 1)
    assert man["link"]["hold_frames"] > 4 and man["link"]["dead_limit_ms"] >= 1500  # 0.5 s
    for m in man["modules"]:
        assert [p["pin"] for p in m["pins"] if p["use"] != "link"] == [12]
        assert m["dead_ticks"] * 100 >= man["link"]["dead_limit_ms"]  # NN ticks: 100 ms
        t = m["timing"]
        assert 0.3 < t["nominal_transition_s"] < t["first_transition_s"] < 1.5  # an estimate
    wiring = (tmp_path / "b" / "WIRING.md").read_text()
    assert "bypass" in wiring and "P13" not in wiring and "(the join)" in wiring


def test_compile_output_rules(tmp_path: Path) -> None:
    """A folder is made with the umask, a foreign one needs --force, a path under a file or
    around the input is refused before any work (one line, exit 2)."""
    import os
    import stat

    ctrl = tmp_path / "c.json"
    ctrl.write_text(CA.read_text())
    old = os.umask(0o022)
    try:
        assert main(["compile", str(ctrl), "-o", str(tmp_path / "b"), "-q"]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "b").stat().st_mode) == 0o755
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert main(["compile", str(ctrl), "-o", str(mine), "-q"]) == 2
    assert (mine / "notes.txt").read_text() == "keep"
    assert main(["compile", str(ctrl), "-o", str(mine), "-q", "--force"]) == 0
    assert buildfile.is_build(mine)
    (tmp_path / "file").write_text("x")
    assert main(["compile", str(ctrl), "-o", str(tmp_path / "file" / "b"), "-q"]) == 2
    assert main(["compile", str(ctrl), "-o", str(tmp_path), "-q", "--force"]) == 2
    assert ctrl.is_file()
