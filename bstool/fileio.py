"""Reading user files with precise errors, and writing outputs atomically (write, then rename)."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from bstool import outputs
from bstool.errors import InputError


def read_json(path: str | os.PathLike[str], what: str = "JSON file") -> Any:
    """Load a JSON file; a missing file or a syntax error becomes an :class:`InputError`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{what} not found: {p}", hint="check the path") from None
    except IsADirectoryError:
        raise InputError(f"{what} is a directory, expected a file: {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {what} {p}: {exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{p}:{exc.lineno}:{exc.colno}: malformed JSON in {what}: {exc.msg}",
            hint="fix the file or regenerate it",
        ) from None


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; rename it over ``path`` only if the block succeeds.

    A crash, an exception or Ctrl-C inside the block leaves ``path`` as it was.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    outputs.clean_stale(target)  # what a killed writer of this file left
    fd, tmp = tempfile.mkstemp(
        prefix=outputs.temp_file_prefix(target), suffix=".tmp", dir=target.parent
    )
    os.chmod(tmp, 0o666 & ~outputs.umask())  # mkstemp makes 0600; give what open() would
    try:
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path: str | os.PathLike[str], text: str) -> None:
    with atomic_open(path, "w") as fh:
        fh.write(text)


def write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def write_json(path: str | os.PathLike[str], obj: Any, *, indent: int | None = 1) -> None:
    """Write JSON deterministically (sorted keys are *not* forced: field order is the format's)."""
    write_text(path, json.dumps(obj, indent=indent) + "\n")
