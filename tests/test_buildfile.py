"""The build folder format (bstool.buildfile, bstool.build/1): round trip, precise errors, image
verification, and what counts as a build."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import FakeModule, TracedBuild, write_fake_build

from bstool import buildfile
from bstool.errors import BuildError, InputError
from bstool.moduleid import ModuleId

GOLDEN = Path(__file__).parent / "golden" / "compile"


@pytest.mark.parametrize("model", ["ca2ddiff", "nnsin"])
def test_golden_manifests_round_trip_byte_for_byte(model: str) -> None:
    path = GOLDEN / model / "manifest.json"
    text = path.read_text(encoding="utf-8")
    man = buildfile.from_json(json.loads(text), path)
    assert buildfile.dumps(man) == text
    assert man.format == buildfile.FORMAT and not man.tokenized


def test_a_compiled_build_loads_and_verifies(traced_build: TracedBuild) -> None:
    build = buildfile.load(traced_build("ca1d"))
    assert (build.legs, build.modules) == (5, 6) and build.manifest.tokenized
    m = build.module(ModuleId(2, 3))
    assert m.label == "L2.M3" and m.servo_pin == 12 and m.ram_map is not None
    assert set(build.images(ModuleId(2, 3))) == {s.slot for s in m.slots}
    assert buildfile.is_build(build.root)
    text = (build.root / buildfile.MANIFEST_FILE).read_text(encoding="utf-8")
    assert buildfile.dumps(build.manifest) == text


def _fake(tmp_path: Path) -> Path:
    return write_fake_build(tmp_path / "b", [FakeModule(ModuleId(0, 0), {0: bytes(2048)})])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda m: m.update(period_s="fast"), r"period_s: expected a number, got str"),
        (lambda m: m["robot"].pop("legs"), r"robot\.legs: expected an integer, got nothing"),
        (lambda m: m["modules"][0].update(module="9.9"), r"modules\[0\]\.module: unknown module"),
        (lambda m: m["modules"][0]["slots"][0].update(slot=True), r"slots\[0\]\.slot"),
        (lambda m: m.update(links={}), r"links: expected a list"),
        (lambda m: m["modules"][0].update(ram_map={"state": ["dword", 1]}), r"ram_map\.state"),
        (lambda m: m.update(format="bstool.build/2"), r"expected format bstool\.build/1"),
    ],
)
def test_errors_name_the_file_and_the_field(tmp_path: Path, change: object, message: str) -> None:
    root = _fake(tmp_path)
    path = root / buildfile.MANIFEST_FILE
    obj = json.loads(path.read_text())
    change(obj)  # type: ignore[operator]
    path.write_text(json.dumps(obj))
    with pytest.raises(InputError, match=message) as err:
        buildfile.load(root)
    assert str(path) in err.value.message and err.value.hint


def test_verify_refuses_changed_images_and_sources_only_builds(tmp_path: Path) -> None:
    root = _fake(tmp_path)
    buildfile.load(root)
    image = root / "modules" / "L0.M0" / "slot0.eeprom"
    image.write_bytes(b"\x01" + image.read_bytes()[1:])
    buildfile.load(root, verify=False)  # reading the manifest alone is fine
    with pytest.raises(BuildError, match="differs from the manifest's sha256") as err:
        buildfile.load(root)
    assert err.value.hint and "bstool compile" in err.value.hint
    path = root / buildfile.MANIFEST_FILE
    obj = json.loads(path.read_text())
    obj["tokenized"] = False
    path.write_text(json.dumps(obj))
    with pytest.raises(BuildError, match="sources only"):
        buildfile.load(root)


def test_a_folder_is_a_build_by_its_format_not_its_file_name(tmp_path: Path) -> None:
    assert not buildfile.is_build(tmp_path)
    (tmp_path / "manifest.json").write_text('{"name": "a web app"}')
    assert not buildfile.is_build(tmp_path)
    (tmp_path / "manifest.json").write_text("not json")
    assert not buildfile.is_build(tmp_path)
    assert buildfile.is_build(_fake(tmp_path))
