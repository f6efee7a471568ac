"""Vectorised state sequences for a whole population at once: shape (P, T+1, n, m), uint8.

The controllers are open loop, so a candidate's whole run is known before any physics. These
functions compute every candidate's sequence with numpy; they are tested equal to the plain
per-module code in :mod:`bstool.controllers.reference`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import numpy.typing as npt

from bstool.controllers.angles import K, angle_table, angles_to_states
from bstool.controllers.reference import CA_MODELS, NN_MODELS, ca_neighbours

Cell = tuple[int, int]
U8 = npt.NDArray[np.uint8]
IntArray = npt.NDArray[np.integer]


def _failed_mask(legs: int, modules: int, failed: Iterable[Cell]) -> npt.NDArray[np.bool_]:
    mask = np.zeros((legs, modules), dtype=bool)
    for i, j in failed:
        mask[i, j] = True
    return mask


def ca_sequences(
    model: str,
    initial: IntArray,
    rules: IntArray,
    transitions: int,
    failed: Iterable[Cell] = (),
    views: Mapping[tuple[Cell, Cell], int] | None = None,
) -> U8:
    """CA runs for P candidates.

    ``initial``: (P, n, m) states; ``rules``: (P, 4096) for ca1d/ca2dsing, (P, 2, 4096)
    (control rule, leg rule) for ca2ddiff. Synchronous updates; failed cells keep R^0.
    ``views`` maps (reader, neighbour) to the state the reader reads for that neighbour in every
    transition instead of the neighbour's own (a per-link held state, the same for all P).
    """
    if model not in CA_MODELS:
        raise ValueError(f"not a CA model: {model!r}")
    init = np.asarray(initial, dtype=np.uint8)
    p, n, m = init.shape
    table = np.asarray(rules, dtype=np.uint8).reshape(p, -1)
    size = K**3
    cells = n * m
    left = np.empty(cells, dtype=np.intp)
    right = np.empty(cells, dtype=np.intp)
    offset = np.zeros(cells, dtype=np.intp)
    for i in range(n):
        for j in range(m):
            (li, lj), (ri, rj) = ca_neighbours(model, n, m, i, j)
            left[i * m + j] = li * m + lj
            right[i * m + j] = ri * m + rj
            if model == "ca2ddiff" and j > 0:
                offset[i * m + j] = size
    frozen = _failed_mask(n, m, failed).reshape(cells)
    seen_l, seen_r = _views(model, n, m, views or {})
    out = np.empty((p, transitions + 1, cells), dtype=np.uint8)
    state = init.reshape(p, cells)
    out[:, 0] = state
    s = state.astype(np.intp)
    for t in range(1, transitions + 1):
        lv, rv = s[:, left], s[:, right]
        for cell, value in seen_l.items():
            lv[:, cell] = value
        for cell, value in seen_r.items():
            rv[:, cell] = value
        idx = (K * K) * lv + K * s + rv + offset
        nxt = np.take_along_axis(table, idx, axis=1).astype(np.intp)
        if frozen.any():
            nxt[:, frozen] = s[:, frozen]
        out[:, t] = nxt
        s = nxt
    return out.reshape(p, transitions + 1, n, m)


def _views(
    model: str, legs: int, modules: int, views: Mapping[tuple[Cell, Cell], int]
) -> tuple[dict[int, int], dict[int, int]]:
    """Flat reader index -> the state it reads on its left and on its right side."""
    seen_l: dict[int, int] = {}
    seen_r: dict[int, int] = {}
    for (reader, source), value in views.items():
        left, right = ca_neighbours(model, legs, modules, *reader)
        if source not in (left, right):
            raise ValueError(f"cell {source} is not a neighbour of {reader}")
        flat = reader[0] * modules + reader[1]
        if left == source:
            seen_l[flat] = int(value)
        if right == source:
            seen_r[flat] = int(value)
    return seen_l, seen_r


def _activate(model: str, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    if model == "nnsin":
        return np.pi / 3 * np.sin(x)
    return (2 * np.pi) / (3 * (1 + np.exp(-x))) - np.pi / 3


def nn_leg_tables(
    model: str, weights: IntArray, fixed: IntArray | None = None, k: int = K
) -> npt.NDArray[np.int64]:
    """Leg states for every lead state: (P, n, k, m); ``[p, i, s]`` = leg i when its lead is s.

    A leg is a function of its lead's state alone (eq. 11 reads only upstream t+1 states).
    ``fixed`` (P, n, m) holds the state of failed modules, −1 where the module works.
    """
    if model not in NN_MODELS:
        raise ValueError(f"not an NN model: {model!r}")
    w = np.asarray(weights, dtype=np.float64)
    p, n, m, _ = w.shape
    angles = angle_table(k)
    legs = np.empty((p, n, k, m), dtype=np.int64)
    legs[..., 0] = np.arange(k)
    if fixed is not None:
        f0 = fixed[:, :, 0][:, :, None]
        legs[..., 0] = np.where(f0 >= 0, f0, legs[..., 0])
    phis = np.empty((p, n, k, m), dtype=np.float64)
    phis[..., 0] = angles[legs[..., 0]]
    for j in range(1, m):
        x = np.zeros((p, n, k), dtype=np.float64)
        for a in range(j):
            x = x + phis[..., a] * w[:, :, a, j][:, :, None]
        state = angles_to_states(_activate(model, x), k)
        if fixed is not None:
            fj = fixed[:, :, j][:, :, None]
            state = np.where(fj >= 0, fj, state)
        legs[..., j] = state
        phis[..., j] = angles[state]
    return legs


def nn_initial(model: str, leads: IntArray, weights: IntArray, k: int = K) -> npt.NDArray[np.int64]:
    """R^0 (P, n, m): every leg propagated from its lead's initial state."""
    tables = nn_leg_tables(model, weights, None, k)
    lead = np.asarray(leads, dtype=np.intp)
    return np.take_along_axis(tables, lead[:, :, None, None], axis=2)[:, :, 0, :]


def nn_sequences(
    model: str,
    leads: IntArray,
    weights: IntArray,
    transitions: int,
    failed: Iterable[Cell] = (),
    k: int = K,
) -> U8:
    """NN runs for P candidates: ``leads`` (P, n) initial lead states, ``weights`` (P, n, m, m)."""
    lead = np.asarray(leads, dtype=np.intp)
    w = np.asarray(weights)
    _, n, m, _ = w.shape
    r0 = nn_initial(model, lead, w, k)
    mask = _failed_mask(n, m, failed)
    if mask.any():
        fixed = np.where(mask[None], r0, -1)
        tables = nn_leg_tables(model, w, fixed, k)
    else:
        tables = nn_leg_tables(model, w, None, k)
    t = np.arange(transitions + 1)
    lead_t = (lead[:, :, None] + t[None, None, :]) % k  # eq. 10
    lead_t = np.where(mask[None, :, 0, None], lead[:, :, None], lead_t)
    seq = np.take_along_axis(tables, lead_t[..., None], axis=2)  # (P, n, T+1, m)
    seq[:, :, 0, :] = r0
    return np.ascontiguousarray(seq.transpose(0, 2, 1, 3)).astype(np.uint8)


def nn_continue(
    model: str,
    frame: IntArray,
    weights: IntArray,
    transitions: int,
    failed: Iterable[Cell] = (),
    k: int = K,
) -> npt.NDArray[np.int64]:
    """One NN run (T+1, n, m) that starts from the frame R^t (n, m) instead of power-up:
    ``failed`` cells hold their state in ``frame``; working leads count on (eq. 10) and every
    leg is propagated from its lead with the held states fixed (eq. 11)."""
    start = np.asarray(frame, dtype=np.int64)
    w = np.asarray(weights)[None]
    n, m = start.shape
    mask = _failed_mask(n, m, failed)
    fixed = np.where(mask, start, -1)[None]
    tables = nn_leg_tables(model, w, fixed, k)[0]  # (n, k, m)
    t = np.arange(transitions + 1)
    lead_t = np.where(mask[:, 0, None], start[:, 0, None], (start[:, 0, None] + t[None, :]) % k)
    seq = np.take_along_axis(tables, lead_t[..., None], axis=1)  # (n, T+1, m)
    out = np.ascontiguousarray(seq.transpose(1, 0, 2)).astype(np.int64)
    out[0] = start
    return out
