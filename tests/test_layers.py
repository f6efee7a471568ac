"""Imports that lint-imports cannot see: the package root ``bstool/__init__.py`` sits above
every layer (it re-exports the API), so a library module that imports a name from it runs
back up the layers; and the flash library gets its compiler from its caller."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUBPACKAGES = {p.name for p in (ROOT / "bstool").iterdir() if p.is_dir()} | {
    p.stem for p in (ROOT / "bstool").glob("*.py")
}


def _root_imports(path: Path) -> list[str]:
    """Names a module takes from the package root itself (not from its submodules)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module == "bstool" and node.level == 0:
            found += [a.name for a in node.names if a.name not in SUBPACKAGES]
    return found


def test_no_library_module_imports_from_the_package_root() -> None:
    offenders = {
        str(p.relative_to(ROOT)): names
        for folder in ("bstool", "hil_mock")
        for p in sorted((ROOT / folder).rglob("*.py"))
        if p != ROOT / "bstool" / "__init__.py" and (names := _root_imports(p))
    }
    assert offenders == {}, "import these from their own module (e.g. bstool.version)"


def test_flash_does_not_import_compile() -> None:
    """The flash library is handed compile_controller by its caller (commands/flash, api)."""
    for path in (ROOT / "bstool" / "flash").glob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)] + [
            a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
        ]
        assert not [m for m in modules if m.startswith("bstool.compile")], path.name


def test_the_version_has_one_home() -> None:
    import bstool
    from bstool.version import __version__

    assert bstool.__version__ == __version__
