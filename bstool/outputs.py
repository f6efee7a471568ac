"""Where outputs may go: checks made before the work starts, and folders replaced in one step.

Every command that writes checks its output paths first (:func:`check_file`, :func:`check_dir`),
so a path it cannot write costs one clear line and no work. Folders are built beside their
target and swapped in with renames (:func:`staged_dir`). Temporaries carry the writer's process
id (``.NAME.new-PID-xxxx``, ``.NAME.old-PID-xxxx``, ``.NAME.PID-xxxx.tmp``), so the next run can
remove what a killed run left (:func:`clean_stale`) without touching a live run's files.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from bstool.errors import InputError

_STALE = re.compile(r"^\.(?P<name>.+)\.(?:(?:new|old)-(?P<pid>\d+)-.+|(?P<fpid>\d+)-.+\.tmp)$")


def umask() -> int:
    """The process's umask (read without changing it for longer than one call)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _writable_parent(path: Path, what: str) -> None:
    """The nearest existing ancestor of ``path`` must be a writable folder."""
    parent = path.parent if str(path.parent) else Path(".")
    probe = parent
    while not probe.exists():
        if probe.is_symlink():  # a dangling link
            raise InputError(f"cannot write {what} {path}: {probe} is a broken link")
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise InputError(
            f"cannot write {what} {path}: {probe} is a file, not a folder",
            hint="choose an output path inside a folder",
        )
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(
            f"cannot write {what} {path}: no permission to write in {probe}",
            hint="choose a folder you can write to",
        )


def check_file(path: str | os.PathLike[str], what: str = "output file") -> Path:
    """Check, before any work, that ``path`` can be written as a file; return it as a Path."""
    p = Path(path)
    if p.is_dir():
        raise InputError(
            f"cannot write {what} {p}: it is a folder", hint="give a file name, not a folder"
        )
    if p.exists() and not os.access(p, os.W_OK):
        raise InputError(f"cannot write {what} {p}: the file is read-only")
    _writable_parent(p, what)
    return p


def check_dir(
    path: str | os.PathLike[str],
    what: str = "output folder",
    *,
    force: bool = False,
    ours: Callable[[Path], bool] | None = None,
    protect: tuple[str | os.PathLike[str], ...] = (),
) -> Path:
    """Check, before any work, that ``path`` may be (re)written as a whole folder.

    A folder that exists and is not empty is refused unless ``ours(path)`` says the command made
    it (e.g. a previous build) or ``force`` is given. ``protect`` names paths the output must
    never replace or contain (e.g. the inputs), whatever ``force`` says.
    """
    p = Path(path)
    resolved = p.resolve()
    for inp in protect:
        q = Path(inp).resolve()
        if resolved == q or resolved in q.parents:
            raise InputError(
                f"{what} {p} would replace the input {inp}",
                hint="write the output to another folder",
            )
    if p.exists() and not p.is_dir():
        raise InputError(
            f"cannot write {what} {p}: it is a file, not a folder",
            hint="choose a new folder name",
        )
    if p.is_dir() and any(p.iterdir()) and not force and not (ours and ours(p)):
        raise InputError(
            f"{what} {p} is not empty and was not made by this command",
            hint="choose a new or empty folder, or add --force to replace it",
        )
    if p.is_dir() and not os.access(p.parent if str(p.parent) else Path("."), os.W_OK):
        raise InputError(f"cannot replace {what} {p}: no permission to write in {p.parent}")
    _writable_parent(p, what)
    return p


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` still runs (this one included): its temporaries are not stale."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries beside ``path`` that a killed writer of ``path`` left behind.

    A writer killed between :func:`staged_dir`'s two renames has moved the old folder aside
    and not yet put the new one in place: the old one is put back, so no kill loses it.
    """
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    removed: list[Path] = []
    if not parent.is_dir():
        return removed
    for entry in parent.iterdir():
        m = _STALE.match(entry.name)
        if not m or m.group("name") != p.name:
            continue
        pid = int(m.group("pid") or m.group("fpid"))
        if process_alive(pid):
            continue
        previous = entry / "previous"
        if ".old-" in entry.name and previous.exists() and not (p.exists() or p.is_symlink()):
            # killed between its two renames: the new folder never arrived; put the old back
            os.replace(previous, p)
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            with suppress(FileNotFoundError):
                entry.unlink()
        removed.append(entry)
    return removed


def temp_file_prefix(target: Path) -> str:
    """The prefix of an atomic write's temporary file beside ``target`` (see clean_stale)."""
    return f".{target.name}.{os.getpid()}-"


@contextmanager
def staged_dir(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a fresh folder beside ``path``; on success it replaces ``path`` in one rename.

    The previous folder (if any) is removed only after the new one is in place; an exception or
    a kill inside the block leaves ``path`` as it was (the next run cleans the temporaries).
    The folder gets the user's umask, as ``mkdir`` would give it.
    """
    target = Path(path)
    clean_stale(target)
    parent = target.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.new-{os.getpid()}-", dir=parent))
    os.chmod(tmp, 0o777 & ~umask())  # mkdtemp makes 0700
    try:
        yield tmp
        old = None
        if target.exists() or target.is_symlink():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-{os.getpid()}-", dir=parent))
            os.replace(target, old / "previous")
        try:
            os.replace(tmp, target)
        except BaseException:
            if old is not None:  # put the previous folder back
                os.replace(old / "previous", target)
                old.rmdir()
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
