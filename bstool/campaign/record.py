"""What a campaign has done, kept in DIR/campaign.json: per run the wall time spent on it, how
many of its generations were made by the campaign and how many it found made (a run folder it
adopted), the equivalent ``bstool evolve`` command; per session of ``bstool campaign`` its
command line, start, end and wall time. Rewritten atomically after every change.

And a lock (DIR/.campaign.lock, holding the process id) so that two campaigns never write one
folder; a lock whose process is gone is taken over.
"""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bstool import fileio, outputs
from bstool.errors import InputError
from bstool.version import __version__

RECORD_FILE = "campaign.json"
RECORD_FORMAT = "bstool.campaign-record/1"
LOCK_FILE = ".campaign.lock"


def now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


@dataclass
class RunRecord:
    command: str = ""
    wall_s: float = 0.0  # time this campaign spent evolving the run (all sessions)
    steps: int = 0  # generations the campaign evolved
    adopted_steps: int = 0  # generations already in the folder when the campaign first saw it
    total_steps: int = 0
    finished: str | None = None  # when the run's last generation was saved (ISO 8601, UTC)


@dataclass
class Session:
    command: str
    started: str
    ended: str | None = None
    wall_s: float = 0.0
    outcome: str = "running"  # finished | interrupted | failed | running
    bstool_version: str = __version__


@dataclass
class Record:
    runs: dict[str, RunRecord] = field(default_factory=dict)
    sessions: list[Session] = field(default_factory=list)

    def run(self, name: str) -> RunRecord:
        return self.runs.setdefault(name, RunRecord())

    @property
    def wall_s(self) -> float:
        """The campaign's wall time: every session of ``bstool campaign`` on this folder."""
        return float(sum(s.wall_s for s in self.sessions))

    def to_json(self) -> dict[str, Any]:
        return {
            "format": RECORD_FORMAT,
            "runs": {k: asdict(v) for k, v in self.runs.items()},
            "sessions": [asdict(s) for s in self.sessions],
        }


def load(folder: str | os.PathLike[str]) -> Record:
    """The record of a campaign folder (empty when there is none yet)."""
    path = Path(folder) / RECORD_FILE
    if not path.exists():
        return Record()
    data = fileio.read_json(path, "campaign record")
    try:
        if data.get("format") != RECORD_FORMAT:
            raise ValueError(f"format {data.get('format')!r}, expected {RECORD_FORMAT!r}")
        runs = {str(k): RunRecord(**v) for k, v in data["runs"].items()}
        sessions = [Session(**s) for s in data["sessions"]]
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(
            f"cannot read the campaign record {path}: {exc}",
            hint="it is written by bstool campaign; remove it to start a new record",
        ) from None
    return Record(runs, sessions)


def save(folder: str | os.PathLike[str], record: Record) -> None:
    fileio.write_json(Path(folder) / RECORD_FILE, record.to_json())


@contextmanager
def lock(folder: str | os.PathLike[str]) -> Iterator[None]:
    """Hold DIR/.campaign.lock while the block runs; refuse if a live process holds it."""
    path = Path(folder) / LOCK_FILE
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666 & ~outputs.umask())
        except FileExistsError:
            try:
                pid = int(path.read_text(encoding="utf-8").strip() or 0)
            except (OSError, ValueError):
                pid = 0
            if pid and outputs.process_alive(pid):
                raise InputError(
                    f"another bstool campaign (process {pid}) is running in {folder}",
                    hint="wait for it to end, or stop it (Ctrl-C leaves it resumable)",
                ) from None
            with suppress(FileNotFoundError):
                path.unlink()  # left by a campaign that was killed
            continue
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(f"{os.getpid()}\n")
        break
    else:  # pragma: no cover - another process took it between our two tries
        raise InputError(f"cannot take the lock {path}", hint="try again")
    try:
        yield
    finally:
        with suppress(FileNotFoundError):
            path.unlink()
