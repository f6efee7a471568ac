"""The measurement program: which loops it runs, rendered from ``templates/pbasic/probe.bsx.j2``
and tokenized in memory.

Each *kind* is a loop body (nothing, an assignment, a long expression, PAUSE/PULSOUT/SERIN
timeout with a unit count in ``p``, SEROUT of 1 or 3 bytes). The program runs every kind twice,
``n_short`` and ``n_long`` iterations, each loop preceded by a DEBUG marker byte (its segment
number), all short loops first then all long ones (a late marker then spoils two different
kinds, never both loops of one), and repeats the whole ``repeats`` times. The host times the
markers; one repeat's long minus short loop cancels the markers' own cost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import jinja2

from bstool.compile.render import templates_dir
from bstool.compile.timing import PAD_PIN
from bstool.errors import BuildError
from bstool.timingfile import DEFAULT, TimingModel
from bstool.tokenizer import SlotImage, tokenize_source
from bstool.wire import announce

TEMPLATE = "probe.bsx.j2"
HEADER = "bstool probe 1"
END_MARKER = 250
SHORT_FRACTION = 0.2  # short loop = 1/5 of the long one
DEBUG_MODE = announce.BAUDMODE  # 9600 baud, the mode of the marker and SEROUT bytes


@dataclass(frozen=True)
class Kind:
    """One loop body. ``param``: the value of ``p`` (unit count); ``unit``: what p counts."""

    name: str
    body: tuple[str, ...]
    param: int = 0
    unit: str | None = None  # "pause" | "pulsout" | "serin": the body waits p units
    items: int = 0  # SEROUT bytes


def kinds(pin: int = PAD_PIN) -> tuple[Kind, ...]:
    return (
        Kind("empty", ()),
        Kind("assign", ("x = x + 1",)),
        Kind("expression", ("x = x * 3 + y / 5 - 7 ^ y",)),
        Kind("pause_1", ("PAUSE p",), 1, "pause"),
        Kind("pause_20", ("PAUSE p",), 20, "pause"),
        Kind("pulsout_125", (f"PULSOUT {pin}, p",), 125, "pulsout"),
        Kind("pulsout_25000", (f"PULSOUT {pin}, p",), 25000, "pulsout"),
        Kind("serin_1", (f"SERIN {pin}, {DEBUG_MODE}, p, {{label}}, [x]",), 1, "serin"),
        Kind("serin_20", (f"SERIN {pin}, {DEBUG_MODE}, p, {{label}}, [x]",), 20, "serin"),
        Kind("serout_1", (f"SEROUT {pin}, {DEBUG_MODE}, [x]",), items=1),
        Kind("serout_3", (f"SEROUT {pin}, {DEBUG_MODE}, [x, x, x]",), items=3),
    )


INSTRUCTION_KINDS = ("empty", "assign", "expression")


@dataclass
class Segment:
    kind: Kind
    n: int
    marker: int
    label: str | None = None
    body_lines: tuple[str, ...] = ()


@dataclass
class KindInfo:
    """Token bits and statement count of one iteration (body + NEXT), from the tokenizer."""

    statements: int
    bits: int
    model_us: float  # one iteration on the default model, waits included


@dataclass
class ProbeProgram:
    source: str
    image: SlotImage
    repeats: int
    segments: list[Segment]
    info: dict[str, KindInfo] = field(default_factory=dict)

    @property
    def markers_per_repeat(self) -> int:
        return len(self.segments) + 1

    def expected_seconds(self, model: TimingModel = DEFAULT, ratio: float = 1.0) -> float:
        """The program's duration on ``model`` with instructions × ``ratio`` (roughly)."""
        total = 0.0
        for s in self.segments:
            total += s.n * iteration_us(s.kind, self.info[s.kind.name], model, ratio)
        return self.repeats * total / 1e6


def wait_us(kind: Kind, model: TimingModel = DEFAULT) -> float:
    """The waits of one iteration of ``kind`` (PAUSE, pulse, SERIN timeout, SEROUT bytes)."""
    p = kind.param
    if kind.unit == "pause":
        return p * model.pause_unit_ms.value * 1000
    if kind.unit == "pulsout":
        return p * model.pulsout_unit_us.value
    if kind.unit == "serin":
        return p * model.serin_unit_ms.value * 1000
    return kind.items * model.serout_item_us.value


def iteration_us(kind: Kind, info: KindInfo, model: TimingModel, ratio: float = 1.0) -> float:
    instr = info.statements * model.base_us.value + info.bits * model.per_bit_us.value
    return instr * ratio + wait_us(kind, model)


@lru_cache(maxsize=1)
def _template() -> jinja2.Template:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
    )
    return env.get_template(TEMPLATE)


def build(*, quick: bool = False, repeats: int | None = None, pin: int = PAD_PIN) -> ProbeProgram:
    """Render and tokenize the probe program. Long loops last about 0.4 s on the default model
    (``quick``: 0.15 s), over 5 repeats (``quick``: 3)."""
    long_s = 0.15 if quick else 0.4
    reps = repeats if repeats is not None else (3 if quick else 5)
    ks = kinds(pin)
    # the first pass only measures the statements' bits (loop counts do not change them much)
    probe = _render(ks, {k.name: 10 for k in ks}, reps, pin)
    info = _kind_info(probe, ks)
    longs = {k.name: max(10, round(long_s * 1e6 / info[k.name].model_us)) for k in ks}
    program = _render(ks, longs, reps, pin)
    program.info = _kind_info(program, ks)
    return program


def _render(ks: tuple[Kind, ...], longs: dict[str, int], repeats: int, pin: int) -> ProbeProgram:
    segments: list[Segment] = []
    for length in ("short", "long"):
        for k in ks:
            n = longs[k.name]
            n = max(2, round(n * SHORT_FRACTION)) if length == "short" else n
            marker = len(segments) + 1
            label = f"T{marker}" if "{label}" in "".join(k.body) else None
            lines = tuple(
                f"{b.format(label=label)} ' seg {marker} body" for b in k.body
            )  # the tag finds the statement's bits in the tokenizer's table
            segments.append(Segment(k, n, marker, label, lines))
    ctx = {
        "header": HEADER,
        "repeats": repeats,
        "pin": pin,
        "end_marker": END_MARKER,
        "segments": [_segment_context(s) for s in segments],
    }
    source = _template().render(**ctx)
    project = tokenize_source(source, "probe.bsx")
    return ProbeProgram(source, project.slots[0], repeats, segments)


def _segment_context(s: Segment) -> dict[str, object]:
    return {"n": s.n, "param": s.kind.param, "marker": s.marker, "body": s.body_lines,
            "label": s.label}  # fmt: skip


def _kind_info(program: ProbeProgram, ks: tuple[Kind, ...]) -> dict[str, KindInfo]:
    lines = program.source.splitlines()
    bits_at = {line: bits for line, _bit, bits in program.image.statements}
    out: dict[str, KindInfo] = {}
    for seg in program.segments:
        if seg.kind.name in out:
            continue
        tags = (f"' seg {seg.marker} body", f"' seg {seg.marker} next")
        found = [(i + 1) for i, text in enumerate(lines) if text.rstrip().endswith(tags)]
        missing = [n for n in found if n not in bits_at]
        if len(found) != len(seg.kind.body) + 1 or missing:
            raise BuildError(f"probe program: cannot find the statements of {seg.kind.name}")
        bits = sum(bits_at[n] for n in found)
        base = KindInfo(len(found), bits, 0.0)
        base.model_us = iteration_us(seg.kind, base, DEFAULT)
        out[seg.kind.name] = base
    return out
