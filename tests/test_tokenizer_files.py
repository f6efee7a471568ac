"""Source files the tokenizer reads (the main file and the project files of ``$STAMP``) must be
regular files of at most MAX_SOURCE_BYTES: anything else is a clear error naming the file,
never a hang, a MemoryError or a traceback."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from bstool.cli import main
from bstool.errors import InputError, SourceError
from bstool.tokenizer import tokenize_file
from bstool.tokenizer.sourcefile import MAX_SOURCE_BYTES, read_source

HEAD = "' {$PBASIC 2.5}\nRUN 1\n"
posix_only = pytest.mark.skipif(sys.platform == "win32", reason="POSIX special files")


def _project(tmp_path: Path, name: str) -> Path:
    main_file = tmp_path / "main.bsx"
    main_file.write_text(f"' {{$STAMP BS2sx, {name}}}\n{HEAD}")
    return main_file


def _project_error(main_file: Path) -> SourceError:
    with pytest.raises(SourceError) as info:
        tokenize_file(main_file)
    exc = info.value
    assert (exc.line, exc.column, exc.code) == (1, 18, 153)  # at the name in the directive
    return exc


@posix_only
def test_project_file_dev_zero_is_refused(tmp_path: Path) -> None:
    exc = _project_error(_project(tmp_path, "/dev/zero"))
    assert "/dev/zero" in exc.message and "device" in exc.message and exc.hint


@posix_only
def test_project_file_fifo_is_refused_without_waiting(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "pipe.bsx")  # nobody writes to it: opening to read would block
    exc = _project_error(_project(tmp_path, "pipe.bsx"))
    assert "pipe.bsx" in exc.message and "FIFO" in exc.message


def test_project_file_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    exc = _project_error(_project(tmp_path, "sub"))
    assert "sub" in exc.message and "directory" in exc.message


def test_oversize_project_file_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.bsx"
    with big.open("wb") as handle:
        handle.truncate(MAX_SOURCE_BYTES + 1)  # sparse: no need to write a megabyte
    exc = _project_error(_project(tmp_path, "big.bsx"))
    assert "big.bsx" in exc.message and str(MAX_SOURCE_BYTES) in exc.message


def test_source_of_exactly_the_limit_is_read(tmp_path: Path) -> None:
    text = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\nHIGH 1\n"
    ok = tmp_path / "ok.bsx"
    ok.write_text(text + "'" * (MAX_SOURCE_BYTES - len(text)))
    assert len(read_source(ok)) == MAX_SOURCE_BYTES
    assert tokenize_file(ok).slots[0].program_bytes > 0


@posix_only
@pytest.mark.parametrize("name", ["/dev/zero", "fifo", "dir", "big"])
def test_main_source_must_be_a_regular_file_of_sane_size(tmp_path: Path, name: str) -> None:
    path = Path(name)
    if name == "fifo":
        path = tmp_path / "f.bsx"
        os.mkfifo(path)
    elif name == "dir":
        path = tmp_path / "d.bsx"
        path.mkdir()
    elif name == "big":
        path = tmp_path / "big.bsx"
        with path.open("wb") as handle:
            handle.truncate(MAX_SOURCE_BYTES * 4)
    with pytest.raises(InputError) as info:
        tokenize_file(path)
    assert str(path) in info.value.message and info.value.hint


@posix_only
@pytest.mark.parametrize("name", ["/dev/zero", "fifo", "big"])
def test_tokenize_command_reports_special_and_huge_files(
    tmp_path: Path, name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = Path(name)
    if name == "fifo":
        path = tmp_path / "f.bsx"
        os.mkfifo(path)
    elif name == "big":
        path = tmp_path / "big.bsx"
        with path.open("wb") as handle:
            handle.truncate(MAX_SOURCE_BYTES + 10)
    code = main(["tokenize", str(path), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == InputError.exit_code
    assert str(path) in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@posix_only
def test_unreadable_source_is_an_input_error_with_a_hint(tmp_path: Path) -> None:
    if os.geteuid() == 0:
        pytest.skip("root reads any file")
    path = tmp_path / "secret.bsx"
    path.write_text(HEAD)
    path.chmod(0)
    with pytest.raises(InputError) as info:
        tokenize_file(path)
    assert str(path) in info.value.message and info.value.hint
