"""The controller file, format ``bstool.controller/1`` (best.json): load, validate, save, hash.

Every later stage reads this file, so validation is strict and each error names the field and
what was expected. Decoded fields only (states, rule outputs, weights), never a bit string.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, NoReturn

import numpy as np
import numpy.typing as npt

from bstool import fileio
from bstool.controllers.angles import K
from bstool.controllers.reference import MODELS, NN_MODELS, ca_neighbours, nn_initial_reference
from bstool.controllers.sequences import ca_sequences, nn_continue, nn_sequences
from bstool.errors import InputError
from bstool.moduleid import ModuleId, parse_module
from bstool.version import __version__

FORMAT = "bstool.controller/1"
RULE_SIZE = K**3
_RULE_FIELDS = {
    "ca1d": ("rule",),
    "ca2dsing": ("rule",),
    "ca2ddiff": ("control_rule", "leg_rule"),
    "nnsig": ("weights",),
    "nnsin": ("weights",),
}
_COMMON = ("format", "model", "legs", "modules", "states", "initial_states")
_OPTIONAL = ("fitness", "max_trans", "ga", "seed", "bstool_version", "robot")
_HINT = "see docs/controllers.md for the format, or regenerate the file with `bstool evolve`"

IntArray = npt.NDArray[np.int64]
FailedSpec = Iterable[ModuleId | tuple[int, int] | str]
FailedAtSpec = Mapping[ModuleId, int] | Mapping[tuple[int, int], int] | Mapping[str, int]
Cell = tuple[int, int]
# failed module -> {reader: T_N or (T_N, T2_N)}; modules as ModuleId, (leg, module) or "L.M"
HeldSpec = Mapping[Any, Mapping[Any, int | tuple[int, int]]]


def controller_hash(obj: Controller | Mapping[str, Any]) -> str:
    """sha256 hex of the controller object as canonical JSON (sorted keys, no spaces)."""
    data = obj.to_json() if isinstance(obj, Controller) else obj
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True, eq=False)
class Controller:
    """A validated controller. ``k`` is the file's ``"states"`` (the method name is taken)."""

    model: str
    legs: int
    modules: int
    k: int
    initial_states: IntArray  # (n, m)
    rule: IntArray | None = None  # (4096,) ca1d, ca2dsing
    control_rule: IntArray | None = None  # (4096,) ca2ddiff
    leg_rule: IntArray | None = None  # (4096,) ca2ddiff
    weights: IntArray | None = None  # (n, m, m) nnsig, nnsin
    fitness: float | None = None
    max_trans: int | None = None
    ga: dict[str, Any] | None = None
    seed: int | None = None
    bstool_version: str = field(default=__version__)
    # the robot it was evolved for (bstool.robot.robotfile.Robot.to_json; checked by the robot
    # package when used); None: the default robot, and the key is not written (hashes of
    # controllers evolved without a robot file do not change)
    robot: dict[str, Any] | None = None

    def rules(self) -> IntArray:
        """The CA rule tables: (1, 4096) or (2, 4096) (control rule, leg rule)."""
        if self.model == "ca2ddiff":
            assert self.control_rule is not None and self.leg_rule is not None
            return np.stack([self.control_rule, self.leg_rule])
        assert self.rule is not None
        return self.rule[None, :]

    def failed_cells(self, failed: FailedSpec) -> list[tuple[int, int]]:
        """Failed modules as (leg, module), checked against the robot's size."""
        cells = []
        for item in failed:
            if isinstance(item, str):
                mid = parse_module(item, self.legs, self.modules)
            else:
                mid = ModuleId(*item)
                if not (0 <= mid.leg < self.legs and 0 <= mid.module < self.modules):
                    raise InputError(
                        f"unknown module {mid}: this robot has legs 0..{self.legs - 1} and "
                        f"modules 0..{self.modules - 1}"
                    )
            cells.append((mid.leg, mid.module))
        return cells

    def states(
        self,
        transitions: int,
        failed: FailedSpec = (),
        failed_at: FailedAtSpec | None = None,
        rejoin: FailedAtSpec | None = None,
        held: HeldSpec | None = None,
        rejoin_with: FailedAtSpec | None = None,
    ) -> IntArray:
        """R^0..R^T, shape (T+1, n, m); failed modules keep their R^0 state.

        ``failed_at`` maps modules to the transition T0 at which they fail during the run: such
        a module follows its rule up to S^T0 and then holds S^T0 (T0 = 0 is ``failed``); its
        neighbours (CA) and the modules after it (NN) read the held state.

        ``held`` (CA only) makes a failure per link: ``held[c][N] = T_N`` (0 <= T_N <= T0)
        says neighbour N of the failed module c reads S_c^(T_N) from transition T_N on, while c
        is dead (a power cut between c's exchanges of one transition); neighbours not listed
        read S_c^T0. All T_N = T0 is plain ``failed_at``. ``held[c][N] = (T_N, T2_N)`` makes
        the rejoin per link too: N reads S_c^(T_N) in the transitions T_N <= t < T2_N (T2_N >=
        T_N; without it, until c's ``rejoin``), and c's own state from T2_N on (a rejoin is not
        atomic across wires either: docs/controllers.md "Per-link rejoin").

        ``rejoin`` maps failed modules (``failed`` or ``failed_at``) to the transition T2 >= T0
        at which they come back: the module still shows its held state in R^T2 and from
        R^(T2+1) on follows its rule again, from that held state (CA: its rule on R^T2's
        neighbourhood; NN lead: held + 1, eq. 10; NN non-lead: its upstream t+1 states); from
        R^T2 on every neighbour reads its state again. T2 = T0 is the healthy sequence
        (docs/controllers.md "Rejoin").

        ``rejoin_with`` (CA only) maps rejoining modules to T_R < T0: the module comes back
        with its state of transition T_R (the one a neighbour that went on held for it, older
        than the S^T0 it showed): it shows S^T0 in R^T0, S^(T_R) in R^(T0+1)..R^T2, and
        resumes from S^(T_R) (docs/controllers.md "Rejoin with an older state").
        """
        if transitions < 0:
            raise InputError(f"transitions must be 0 or more, got {transitions}")
        cells = self.failed_cells(failed)
        fail: dict[tuple[int, int], int] = dict.fromkeys(cells, 0)
        for item, when in (failed_at or {}).items():
            (cell,) = self.failed_cells([item])
            if int(when) < 0:
                raise InputError(
                    f"module {ModuleId(*cell)} fails at transition {when}: must be >= 0"
                )
            fail[cell] = min(int(when), fail.get(cell, int(when)))
        back: dict[tuple[int, int], int] = {}
        for item, when in (rejoin or {}).items():
            (cell,) = self.failed_cells([item])
            if cell not in fail:
                raise InputError(
                    f"module {ModuleId(*cell)} rejoins at transition {when} but never fails",
                    hint="give its failure too: --fail L.M or --fail-at L.M@T, then --rejoin "
                    "L.M@T2",
                )
            if int(when) < fail[cell]:
                raise InputError(
                    f"module {ModuleId(*cell)} rejoins at transition {when}, before it fails "
                    f"at {fail[cell]}",
                    hint="the rejoin transition T2 must be >= the failure transition T0",
                )
            back[cell] = int(when)
        links = self._held_links(held or {}, fail)
        older = self._rejoin_with(rejoin_with or {}, fail, back)

        def frozen(t: int) -> list[tuple[int, int]]:
            """Cells holding their state in the transition R^t -> R^(t+1)."""
            return [c for c, t0 in fail.items() if t0 <= t and back.get(c, transitions) > t]

        def views(t: int, done: IntArray) -> dict[tuple[Cell, Cell], int]:
            """(reader, c) -> S_c^(T_N) for the links held in R^t -> R^(t+1)."""
            return {
                (reader, c): int(done[tn][c])
                for (c, reader), (tn, until) in links.items()
                if tn <= t < (back.get(c, transitions) if until is None else until)
            }

        ends = [t for span in links.values() for t in span if t is not None]
        turns = {fail[c] + 1: c for c in older}  # R^(T0+1): c shows its older state from here
        marks = [*fail.values(), *back.values(), *ends, *turns]
        times = sorted({t for t in marks if 0 < t < transitions})
        first = times[0] if times else transitions
        done = self._states(first, frozen(0), views(0, self.initial_states[None])).copy()
        for start, end in zip(times, [*times[1:], transitions], strict=False):
            for c, t_r in older.items():
                if start == fail[c] + 1:
                    done[-1][c] = done[t_r][c]
            more = self._continue(done[-1], end - start, frozen(start), views(start, done))
            done = np.concatenate([done, more[1:]])
        for c, t_r in older.items():  # a run that ends in R^(T0+1)
            if fail[c] + 1 == transitions:
                done[-1][c] = done[t_r][c]
        return done

    def _rejoin_with(
        self, rejoin_with: FailedAtSpec, fail: Mapping[Cell, int], back: Mapping[Cell, int]
    ) -> dict[Cell, int]:
        """``rejoin_with`` checked: c -> T_R."""
        out: dict[Cell, int] = {}
        if rejoin_with and self.model in NN_MODELS:
            raise InputError(
                "a rejoin with an older state (rejoin_with, --rejoin-with) is for CA models only",
                hint="an NN module rejoins from the state its downstream held: --rejoin L.M@T2",
            )
        for item, when in rejoin_with.items():
            (cell,) = self.failed_cells([item])
            c = ModuleId(*cell)
            if cell not in back:
                raise InputError(
                    f"module {c} rejoins with its state of transition {when} but never rejoins",
                    hint="give its failure and rejoin too: --fail-at L.M@T0 --rejoin L.M@T2, "
                    "then --rejoin-with L.M@T_R",
                )
            if not 0 <= int(when) < fail[cell] < back[cell]:
                raise InputError(
                    f"module {c} rejoins with its state of transition {when}: needs "
                    f"0 <= T_R < T0 = {fail[cell]} < T2 = {back[cell]}",
                    hint="--rejoin-with L.M@T_R is an older state than the S^T0 it failed "
                    "with, and it must be away at least one transition (T2 > T0)",
                )
            out[cell] = int(when)
        return out

    def _held_links(
        self, held: HeldSpec, fail: Mapping[Cell, int]
    ) -> dict[tuple[Cell, Cell], tuple[int, int | None]]:
        """``held`` checked: (c, reader) -> (T_N, T2_N or None: until c rejoins)."""
        links: dict[tuple[Cell, Cell], tuple[int, int | None]] = {}
        if held and self.model in NN_MODELS:
            raise InputError(
                "a per-link held state (held, --held-by) is for CA models only",
                hint="an NN module's state reaches the modules after it through one relay: use "
                "--fail-at L.M@T",
            )
        for item, readers in held.items():
            (cell,) = self.failed_cells([item])
            c = ModuleId(*cell)
            if cell not in fail:
                raise InputError(
                    f"module {c} is held by its neighbours but never fails",
                    hint="give its failure too: --fail-at L.M@T, then --held-by N=L.M@T_N",
                )
            readers_of_c = [
                ModuleId(i, j)
                for i in range(self.legs)
                for j in range(self.modules)
                if cell in ca_neighbours(self.model, self.legs, self.modules, i, j)
            ]
            for who, span in readers.items():
                when, until = span if isinstance(span, tuple) else (span, None)
                (reader,) = self.failed_cells([who])
                n = ModuleId(*reader)
                if n not in readers_of_c:
                    names = ", ".join(str(x) for x in readers_of_c)
                    raise InputError(
                        f"module {n} does not read module {c}'s state in model {self.model}",
                        hint=f"the modules that read {c}'s state: {names}",
                    )
                if not 0 <= int(when) <= fail[cell]:
                    raise InputError(
                        f"module {n} holds module {c}'s state of transition {when}: must be "
                        f"0..{fail[cell]} ({c} fails at {fail[cell]} and shows no later state)",
                        hint="--held-by N=L.M@T_N needs T_N <= T of --fail-at L.M@T",
                    )
                if until is not None and int(until) < int(when):
                    raise InputError(
                        f"module {n} reads module {c}'s held state of transition {when} until "
                        f"transition {until}: the end must be >= {when}",
                        hint="--held-by N=L.M@T_N..T2_N needs T2_N >= T_N",
                    )
                links[cell, reader] = (int(when), None if until is None else int(until))
        return links

    def _continue(
        self,
        frame: IntArray,
        transitions: int,
        cells: list[tuple[int, int]],
        views: Mapping[tuple[Cell, Cell], int] | None = None,
    ) -> IntArray:
        """R^t..R^(t+transitions) from frame R^t; ``cells`` hold their state in R^t, readers
        in ``views`` read the given state for that neighbour (CA)."""
        if self.model in NN_MODELS:
            assert self.weights is not None
            return nn_continue(self.model, frame, self.weights, transitions, cells, self.k)
        rules = self.rules()
        seq = ca_sequences(
            self.model,
            np.asarray(frame)[None],
            rules[None] if self.model == "ca2ddiff" else rules,
            transitions,
            cells,
            views,
        )
        return seq[0].astype(np.int64)

    def _states(
        self,
        transitions: int,
        cells: list[tuple[int, int]],
        views: Mapping[tuple[Cell, Cell], int] | None = None,
    ) -> IntArray:
        if self.model in NN_MODELS:
            assert self.weights is not None
            seq = nn_sequences(
                self.model,
                self.initial_states[None, :, 0],
                self.weights[None],
                transitions,
                cells,
                self.k,
            )
        else:
            rules = self.rules()
            seq = ca_sequences(
                self.model,
                self.initial_states[None],
                rules[None] if self.model == "ca2ddiff" else rules,
                transitions,
                cells,
                views,
            )
        return seq[0].astype(np.int64)

    def to_json(self) -> dict[str, Any]:
        obj: dict[str, Any] = {
            "format": FORMAT,
            "model": self.model,
            "legs": self.legs,
            "modules": self.modules,
            "states": self.k,
            "initial_states": self.initial_states.tolist(),
        }
        for name in _RULE_FIELDS[self.model]:
            value = getattr(self, name)
            obj[name] = value.tolist()
        obj["fitness"] = self.fitness
        obj["max_trans"] = self.max_trans
        obj["ga"] = self.ga
        obj["seed"] = self.seed
        obj["bstool_version"] = self.bstool_version
        if self.robot is not None:
            obj["robot"] = self.robot
        return obj

    def hash(self) -> str:
        return controller_hash(self)


def from_json(obj: Any, source: str = "controller") -> Controller:
    """Validate a decoded controller object; errors name ``source`` and the field."""
    v = _Validator(source)
    if not isinstance(obj, dict):
        v.fail("", f"expected a JSON object, got {_kind(obj)}")
    fmt = obj.get("format")
    if fmt != FORMAT:
        v.fail("format", f"expected {FORMAT!r}, got {fmt!r}")
    model = obj.get("model")
    if model not in MODELS:
        v.fail("model", f"expected one of {', '.join(MODELS)}, got {model!r}")
    allowed = set(_COMMON) | set(_RULE_FIELDS[model]) | set(_OPTIONAL)
    for key in obj:
        if key not in allowed:
            other = [m for m, f in _RULE_FIELDS.items() if key in f]
            why = f" (it belongs to {'/'.join(other)})" if other else ""
            v.fail(key, f"unknown field for model {model}{why}")
    for key in (*_COMMON, *_RULE_FIELDS[model]):
        if key not in obj:
            v.fail(key, "missing")
    legs = v.int_in("legs", obj["legs"], 1, 64)
    modules = v.int_in("modules", obj["modules"], 1, 64)
    k = v.int_in("states", obj["states"], K, K)
    initial = v.grid("initial_states", obj["initial_states"], (legs, modules), 0, k - 1)
    fields: dict[str, Any] = {}
    for name in _RULE_FIELDS[model]:
        if name == "weights":
            w = v.grid("weights", obj[name], (legs, modules, modules), 0, 1)
            below = np.argwhere(np.tril(np.ones((modules, modules), dtype=bool)) & (w > 0))
            if len(below):
                i, a, b = below[0]
                v.fail(
                    f"weights[{i}][{a}][{b}]",
                    "expected 0: only weights from module a to module b with a < b are used",
                )
            fields[name] = w
        else:
            fields[name] = v.grid(name, obj[name], (RULE_SIZE,), 0, k - 1)
    if model in NN_MODELS:
        r0 = nn_initial_reference(model, initial[:, 0].tolist(), fields["weights"].tolist(), k)
        for i in range(legs):
            for j in range(1, modules):
                if initial[i, j] != r0[i][j]:
                    v.fail(
                        f"initial_states[{i}][{j}]",
                        f"expected {r0[i][j]}, the state propagated from lead state "
                        f"{initial[i, 0]} through the weights (eq. 11–14), got {initial[i, j]}",
                        hint="for NN models only the leads' initial states are free",
                    )
    fitness = obj.get("fitness")
    if fitness is not None and (not isinstance(fitness, int | float) or isinstance(fitness, bool)):
        v.fail("fitness", f"expected a number or null, got {_kind(fitness)}")
    max_trans = obj.get("max_trans")
    if max_trans is not None:
        v.int_in("max_trans", max_trans, 0, 10**6)
    ga = obj.get("ga")
    if ga is not None and not isinstance(ga, dict):
        v.fail("ga", f"expected an object or null, got {_kind(ga)}")
    seed = obj.get("seed")
    if seed is not None:
        v.int_in("seed", seed, 0, 2**128)
    robot = obj.get("robot")
    if robot is not None and not isinstance(robot, dict):
        v.fail("robot", f"expected an object (a robot's values) or null, got {_kind(robot)}")
    version = obj.get("bstool_version", __version__)
    if not isinstance(version, str):
        v.fail("bstool_version", f"expected a string, got {_kind(version)}")
    return Controller(
        model=model,
        legs=legs,
        modules=modules,
        k=k,
        initial_states=initial,
        fitness=None if fitness is None else float(fitness),
        max_trans=max_trans,
        ga=ga,
        seed=seed,
        bstool_version=version,
        robot=robot,
        **fields,
    )


def make_controller(
    model: str,
    initial_states: Any,
    *,
    rule: Any = None,
    control_rule: Any = None,
    leg_rule: Any = None,
    weights: Any = None,
    fitness: float | None = None,
    max_trans: int | None = None,
    ga: dict[str, Any] | None = None,
    seed: int | None = None,
    robot: dict[str, Any] | None = None,
) -> Controller:
    """Build a validated controller from arrays. NN models read only the leads of
    ``initial_states`` (shape (n, m) or (n,)); the rest is propagated (R^0)."""
    init = np.asarray(initial_states, dtype=np.int64)
    if model in NN_MODELS:
        w = np.asarray(weights, dtype=np.int64)
        leads = init if init.ndim == 1 else init[:, 0]
        init = np.array(nn_initial_reference(model, leads.tolist(), w.tolist(), K))
    obj: dict[str, Any] = {
        "format": FORMAT,
        "model": model,
        "legs": int(init.shape[0]),
        "modules": int(init.shape[1]),
        "states": K,
        "initial_states": init.tolist(),
    }
    given = {"rule": rule, "control_rule": control_rule, "leg_rule": leg_rule, "weights": weights}
    for name in _RULE_FIELDS.get(model, ()):
        obj[name] = np.asarray(given[name]).tolist()
    obj.update(fitness=fitness, max_trans=max_trans, ga=ga, seed=seed, bstool_version=__version__)
    if robot is not None:
        obj["robot"] = robot
    return from_json(obj, f"{model} controller")


def load_controller(path: str | os.PathLike[str]) -> Controller:
    """Read and validate a controller file (``InputError`` naming the field on any problem)."""
    return from_json(fileio.read_json(path, "controller file"), str(path))


def dumps_controller(controller: Controller | Mapping[str, Any]) -> str:
    """JSON text, one field per line (lists kept on one line)."""
    obj = controller.to_json() if isinstance(controller, Controller) else dict(controller)
    items = [
        f" {json.dumps(key)}: {json.dumps(value, separators=(',', ':'))}"
        for key, value in obj.items()
    ]
    return "{\n" + ",\n".join(items) + "\n}\n"


def save_controller(controller: Controller, path: str | os.PathLike[str]) -> None:
    """Write atomically (never a half-written best.json)."""
    fileio.write_text(path, dumps_controller(controller))


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int) and abs(value) >= 10**18:  # str() of a huge int is slow or fails
        return f"an integer of about {int(abs(value).bit_length() * 0.30103) + 1} digits"
    if isinstance(value, int | float):
        return f"the number {value}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return "an object"


class _Validator:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, what: str, hint: str = _HINT) -> NoReturn:
        place = f"field '{where}'" if where else "top level"
        raise InputError(f"{self.source}: {place}: {what}", hint=hint)

    def int_in(self, where: str, value: Any, lo: int, hi: int) -> int:
        if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
            want = f"the integer {lo}" if lo == hi else f"an integer {lo}..{hi}"
            self.fail(where, f"expected {want}, got {_kind(value)}")
        return int(value)

    def grid(self, where: str, value: Any, shape: tuple[int, ...], lo: int, hi: int) -> IntArray:
        """A nested list of ints of exactly ``shape`` with values lo..hi (read-only array)."""
        self._check(where, value, shape, lo, hi)
        arr = np.array(value, dtype=np.int64).reshape(shape)
        arr.setflags(write=False)
        return arr

    def _check(self, where: str, value: Any, shape: tuple[int, ...], lo: int, hi: int) -> None:
        dims = "×".join(str(d) for d in shape)
        if not isinstance(value, list) or len(value) != shape[0]:
            inner = "ints" if len(shape) == 1 else "lists"
            self.fail(where, f"expected a list of {shape[0]} {inner} ({dims}), got {_kind(value)}")
        if len(shape) == 1:
            for idx, x in enumerate(value):
                if type(x) is not int or not lo <= x <= hi:
                    self.fail(f"{where}[{idx}]", f"expected an integer {lo}..{hi}, got {_kind(x)}")
            return
        for idx, row in enumerate(value):
            self._check(f"{where}[{idx}]", row, shape[1:], lo, hi)
