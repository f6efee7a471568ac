"""Reading user files with precise errors, and writing outputs atomically (write, then rename)."""

from __future__ import annotations

import json
import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from bstool import outputs
from bstool.errors import InputError

#: The largest JSON file a command reads (controllers, states, manifests are far smaller).
MAX_JSON_BYTES = 64 * 1024 * 1024


def read_limited(
    path: str | os.PathLike[str], what: str = "file", limit: int = MAX_JSON_BYTES
) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, else an :class:`InputError`.

    A FIFO, a device (``/dev/zero``) or a folder is refused before it is opened, so nothing
    hangs; at most ``limit`` + 1 bytes are read even if the file grows meanwhile.
    """
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise InputError(f"{what} not found: {p}", hint="check the path") from None
    except OSError as exc:
        raise InputError(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{what} is a directory, expected a file: {p}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(
            f"{what} {p} is not a regular file (a pipe or a device)",
            hint="give a file saved on disk",
        )
    too_big = InputError(
        f"{what} {p} is larger than {limit // (1024 * 1024)} MiB", hint="give the right file"
    )
    if st.st_size > limit:
        raise too_big
    try:
        with open(p, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise too_big
    return data


def loads_json(text: str | bytes, where: str, what: str = "JSON file") -> Any:
    """Parse JSON; malformed, absurdly nested or huge-integer input is an :class:`InputError`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{where}:{exc.lineno}:{exc.colno}: malformed JSON in {what}: {exc.msg}",
            hint="fix the file or regenerate it",
        ) from None
    except UnicodeDecodeError:
        raise InputError(f"cannot read {what} {where}: not UTF-8 text") from None
    except RecursionError:
        raise InputError(
            f"{where}: {what} is nested too deeply to be read",
            hint="fix the file or regenerate it",
        ) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise InputError(
            f"{where}: cannot read {what}: {exc}".split("; use sys.")[0],
            hint="fix the file or regenerate it",
        ) from None


def read_json(path: str | os.PathLike[str], what: str = "JSON file") -> Any:
    """Load a JSON file; a missing, oversized, special or malformed file is an InputError."""
    return loads_json(read_limited(path, what), str(Path(path)), what)


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; rename it over ``path`` only if the block succeeds.

    A crash, an exception or Ctrl-C inside the block leaves ``path`` as it was.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        outputs.clean_stale(target)  # what a killed writer of this file left
        fd, tmp = tempfile.mkstemp(
            prefix=outputs.temp_file_prefix(target), suffix=".tmp", dir=target.parent
        )
    except OSError as exc:  # a parent that is a file, no permission, a full disk...
        outputs.check_file(target)  # says which, as one line
        raise InputError(f"cannot write {target}: {exc.strerror or exc}") from None
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
