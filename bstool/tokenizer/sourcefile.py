"""Reading a PBASIC source file: a regular file of sane size, or a clear error.

The main source and the project files its ``$STAMP`` directive names are read here, so a
name like ``/dev/zero``, a FIFO or a directory cannot hang the tokenizer or exhaust memory.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from bstool.errors import InputError

# Far above any source the IDE accepts (10,240 elements; `bstool compile` writes about 10 KB,
# the longest tables seen were 71 KB), small enough to read at once. See docs/tokenizer.md.
MAX_SOURCE_BYTES = 1 << 20
_READ_FLAGS = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_source(path: str | os.PathLike[str]) -> str:
    """The text of the source file ``path`` (UTF-8, undecodable bytes replaced).

    Raises InputError naming the file when it is missing, not a regular file, larger than
    MAX_SOURCE_BYTES or unreadable. The file is opened without blocking and checked through
    its descriptor, so a FIFO is refused rather than waited on.
    """
    p = Path(path)
    try:
        fd = os.open(p, _READ_FLAGS)
    except FileNotFoundError:
        raise InputError(f"source not found: {p}", hint="check the path") from None
    except IsADirectoryError:
        raise InputError(
            f"source {p} is a directory, expected a .bsx file", hint="name a PBASIC file"
        ) from None
    except OSError as exc:
        raise _unreadable(p, exc) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise InputError(
                f"source {p} is {_kind(info.st_mode)}, expected a .bsx file",
                hint="name a regular PBASIC source file",
            )
        if info.st_size > MAX_SOURCE_BYTES:
            raise _too_large(p, info.st_size)
        with os.fdopen(os.dup(fd), "rb") as handle:  # (O_NONBLOCK: no effect on a file)
            data = handle.read(MAX_SOURCE_BYTES + 1)
    except OSError as exc:
        raise _unreadable(p, exc) from None
    finally:
        os.close(fd)
    if len(data) > MAX_SOURCE_BYTES:  # grew while being read
        raise _too_large(p, len(data))
    return data.decode("utf-8", errors="replace")


def _too_large(p: Path, size: int) -> InputError:
    return InputError(
        f"source {p} has {size} bytes, more than the {MAX_SOURCE_BYTES} a PBASIC source may have",
        hint="a BS2sx slot holds 2048 bytes; split the program or its tables across slots",
    )


def _unreadable(p: Path, exc: OSError) -> InputError:
    return InputError(
        f"cannot read {p}: {exc.strerror or exc}",
        hint="check that the file exists and that you may read it",
    )
