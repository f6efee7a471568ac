"""State sequences: validation of arrays and JSON, and failed-module holding.

A state sequence is an integer array (T+1, n, m) with values 0..k-1 (docs/DEVELOPING.md).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bstool import fileio
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.robot.spec import RobotSpec


def validate_states(states: Any, spec: RobotSpec, where: str = "states") -> np.ndarray:
    """Return ``states`` as a C-contiguous int64 array (T+1, n, m), or raise InputError."""
    n, m, k = spec.legs, spec.modules, spec.states
    try:
        arr = np.asarray(states)
    except ValueError:  # ragged nesting
        arr = np.asarray(states, dtype=object)
    if arr.dtype == object or arr.ndim != 3:
        raise InputError(
            f"{where}: expected frames of {n} legs × {m} modules (array of shape (T+1, {n}, {m})),"
            f" got {_describe(states)}",
            hint="a states file is a JSON list of T+1 frames, each a list of n lists of m ints",
        )
    if arr.shape[1:] != (n, m):
        raise InputError(
            f"{where}: wrong robot shape: frames are {arr.shape[1]} legs × {arr.shape[2]} modules,"
            f" the robot has {n} × {m}",
            hint=f"give {n} lists of {m} states per frame",
        )
    if arr.shape[0] < 1:
        raise InputError(f"{where}: no frames", hint="give at least R^0")
    if arr.dtype.kind == "b" or arr.dtype.kind not in "iu":
        if arr.dtype.kind == "f" and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            arr = arr.astype(np.int64)
        else:
            raise InputError(
                f"{where}: states must be integers 0..{k - 1} (got {arr.dtype} values)",
                hint="write states as plain integers",
            )
    bad = np.argwhere((arr < 0) | (arr >= k))
    if len(bad):
        t, i, j = (int(x) for x in bad[0])
        raise InputError(
            f"{where}: state {int(arr[t, i, j])} at frame {t}, leg {i}, module {j} is out of"
            f" range 0..{k - 1} ({len(bad)} bad value{'s' if len(bad) > 1 else ''} in all)",
            hint=f"the robot has {k} states per module",
        )
    return np.ascontiguousarray(arr, dtype=np.int64)


def _describe(obj: Any) -> str:
    if isinstance(obj, np.ndarray):
        return f"an array of shape {obj.shape}"
    if isinstance(obj, list):
        if obj and isinstance(obj[0], list):
            return f"a list of {len(obj)} frames with inconsistent or wrong nesting"
        return f"a flat list of {len(obj)} items"
    return f"a {type(obj).__name__}"


def load_states_file(path: str | Path, spec: RobotSpec) -> np.ndarray:
    """Read a states JSON file (list of T+1 frames of n lists of m ints)."""
    data = fileio.read_json(path, "states file")
    return states_from_json(data, spec, where=str(path))


def states_from_json(data: Any, spec: RobotSpec, where: str = "states") -> np.ndarray:
    if not isinstance(data, list) or not data:
        raise InputError(
            f"{where}: a states file must be a non-empty JSON list of frames,"
            f" got {type(data).__name__}",
            hint="write [[[s, ...] × m] × n] × (T+1) frames, as `bstool states` prints",
        )
    for t, frame in enumerate(data):
        if not isinstance(frame, list) or not all(isinstance(leg, list) for leg in frame):
            raise InputError(
                f"{where}: frame {t} is not a list of {spec.legs} lists of {spec.modules} ints",
                hint="each frame is a list of n legs, each a list of m module states",
            )
        for i, leg in enumerate(frame):
            if len(leg) != spec.modules or len(frame) != spec.legs:
                raise InputError(
                    f"{where}: wrong robot shape at frame {t}: {len(frame)} legs"
                    f" (leg {i} has {len(leg)} modules), the robot has {spec.legs} legs ×"
                    f" {spec.modules} modules",
                    hint=f"give {spec.legs} lists of {spec.modules} states per frame",
                )
            for j, s in enumerate(leg):
                if isinstance(s, bool) or not isinstance(s, int):
                    raise InputError(
                        f"{where}: frame {t}, leg {i}, module {j}: state {s!r} is not an integer",
                        hint=f"states are integers 0..{spec.states - 1}",
                    )
    return validate_states(data, spec, where)


def hold_failed(states: np.ndarray, failed: Iterable[ModuleId]) -> np.ndarray:
    """A copy where each failed module keeps its R^0 state for the whole run (paper §5.1)."""
    out = states.copy()
    for mid in failed:
        out[:, mid.leg, mid.module] = out[0, mid.leg, mid.module]
    return out
