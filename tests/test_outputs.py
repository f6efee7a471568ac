"""Output paths: checked before the work, folders swapped in whole, temporaries of killed runs
removed by the next run, folders made with the user's umask."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from bstool import fileio, outputs
from bstool.errors import InputError


def test_check_file_refuses_a_parent_that_is_a_file(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder"):
        outputs.check_file(tmp_path / "f" / "sub" / "out.png")


def test_check_file_refuses_a_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="it is a folder"):
        outputs.check_file(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_check_file_refuses_an_unwritable_folder(tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o500)
    with pytest.raises(InputError, match="no permission"):
        outputs.check_file(ro / "out.json")


def test_check_file_accepts_new_nested_folders(tmp_path: Path) -> None:
    assert outputs.check_file(tmp_path / "a" / "b" / "c.json") == tmp_path / "a" / "b" / "c.json"


def test_check_dir_refuses_a_foreign_non_empty_folder(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("keep me")
    with pytest.raises(InputError, match="not empty") as info:
        outputs.check_dir(tmp_path)
    assert "--force" in (info.value.hint or "")
    assert outputs.check_dir(tmp_path, force=True) == tmp_path
    assert outputs.check_dir(tmp_path, ours=lambda p: True) == tmp_path


def test_check_dir_never_replaces_its_input(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "best.json").write_text("{}")
    for out in (run, tmp_path):  # the input itself, or a folder holding it
        with pytest.raises(InputError, match="would replace the input"):
            outputs.check_dir(out, force=True, protect=(run / "best.json",))


def test_check_dir_refuses_a_file(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is a file"):
        outputs.check_dir(tmp_path / "f")


def test_staged_dir_swaps_whole_and_keeps_the_old_on_error(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with outputs.staged_dir(out) as tmp:
        (tmp / "a").write_text("1")
    assert (out / "a").read_text() == "1"
    with pytest.raises(RuntimeError), outputs.staged_dir(out) as tmp:
        (tmp / "b").write_text("2")
        raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == ["a"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporaries left


def test_staged_dir_uses_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        with outputs.staged_dir(tmp_path / "out"):
            pass
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "out").stat().st_mode) == 0o755


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_clean_stale_removes_only_dead_writers_temporaries(tmp_path: Path) -> None:
    dead, live = _dead_pid(), os.getpid()
    (tmp_path / f".out.new-{dead}-abc").mkdir()
    (tmp_path / f".out.old-{dead}-abc").mkdir()
    (tmp_path / f".best.json.{dead}-x1.tmp").write_text("half")
    (tmp_path / f".out.new-{live}-def").mkdir()
    (tmp_path / f".other.new-{dead}-abc").mkdir()
    outputs.clean_stale(tmp_path / "out")
    fileio.write_text(tmp_path / "best.json", "{}")  # an atomic write cleans its own
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(["best.json", f".other.new-{dead}-abc", f".out.new-{live}-def"])


def test_atomic_write_of_a_killed_run_is_cleaned_by_the_next(tmp_path: Path) -> None:
    target = tmp_path / "checkpoint.npz"
    code = (
        "import os, sys\n"
        "from bstool import fileio\n"
        "with fileio.atomic_open(sys.argv[1], 'wb') as fh:\n"
        "    fh.write(b'half'); fh.flush(); os._exit(9)\n"
    )
    subprocess.run([sys.executable, "-c", code, str(target)], check=False)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    fileio.write_bytes(target, b"whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint.npz"]
    assert target.read_bytes() == b"whole"


def test_a_kill_between_the_two_renames_gives_the_old_folder_back(tmp_path: Path) -> None:
    dead = _dead_pid()
    aside = tmp_path / f".out.old-{dead}-abc"
    (aside / "previous").mkdir(parents=True)
    (aside / "previous" / "best.json").write_text("keep")
    (tmp_path / f".out.new-{dead}-def").mkdir()  # the new folder, never renamed in
    outputs.clean_stale(tmp_path / "out")
    assert (tmp_path / "out" / "best.json").read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_atomic_write_that_cannot_start_is_an_input_error(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder"):
        fileio.write_text(tmp_path / "f" / "out.json", "{}")
    assert (tmp_path / "f").read_text() == "x"
