"""The wheel's package list (pyproject.toml) matches the tree; the templates are package data."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))


def test_every_package_of_the_tree_is_in_the_wheel() -> None:
    listed = set(_pyproject()["tool"]["setuptools"]["packages"])
    found = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for top in ("bstool", "hil_mock")
        for init in (ROOT / top).rglob("__init__.py")
    }
    assert found <= listed, f"add to [tool.setuptools] packages: {sorted(found - listed)}"
    assert listed - found == {"bstool.templates"}


def test_templates_are_mapped_into_the_package() -> None:
    setuptools = _pyproject()["tool"]["setuptools"]
    assert setuptools["package-dir"] == {"bstool.templates": "templates"}
    assert setuptools["package-data"]["bstool.templates"] == ["pbasic/*.j2"]
    shipped = {p.name for p in (resources.files("bstool.templates") / "pbasic").iterdir()}
    on_disk = {p.name for p in (ROOT / "templates" / "pbasic").glob("*.j2")}
    assert on_disk and shipped >= on_disk


def test_tools_are_pinned_exactly() -> None:
    for req in _pyproject()["project"]["optional-dependencies"]["test"]:
        if not req.startswith("dask"):
            assert "==" in req, f"pin {req} exactly (docs/DEVELOPING.md, Tool pins)"
