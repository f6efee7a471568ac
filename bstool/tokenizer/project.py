"""Entry points: a source (or a multi-slot project) -> EEPROM images and download records."""

from __future__ import annotations

import bisect
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bstool.errors import InputError, SourceError
from bstool.tokenizer import tokens
from bstool.tokenizer.conditional import Conditional
from bstool.tokenizer.diagnostics import HINTS, Failure
from bstool.tokenizer.image import DEFINED_DATA, PROGRAM, UNDEFINED_DATA
from bstool.tokenizer.lexer import BS2P_ONLY, Directives, K, Lexer, prepare, read_directives
from bstool.tokenizer.serial import Serial
from bstool.tokenizer.sourcefile import read_source

TARGET = "BS2SX"
_PROJECT_FILES_HINT = "project files are resolved relative to the main file's folder"


@dataclass
class SlotImage:
    """One tokenized slot: the 2048-byte image and what the programming protocol sends."""

    slot: int
    source: str
    eeprom: bytes
    records: list[bytes]
    program_bytes: int
    data_bytes: int
    undefined_data_bytes: int
    variables_used: int  # bytes of the 26 bytes of variable RAM
    pbasic: str = "2.5"
    statements: list[tuple[int, int, int]] = field(default_factory=list)  # line, bit, bits
    source_lines: list[str] = field(default_factory=list, repr=False)
    # RAM of every VAR, alias included: upper-case name -> ("bit"|"nib"|"byte"|"word", index
    # in units of that size, as in INS/OUTS/DIRS-relative register numbering of bs2sx.md §4)
    variables: dict[str, tuple[str, int]] = field(default_factory=dict)

    @property
    def packets(self) -> bytes:
        return b"".join(self.records)

    def summary(self) -> dict[str, object]:
        return {
            "source": self.source,
            "program_bytes": self.program_bytes,
            "data_bytes": self.data_bytes,
            "undefined_data_bytes": self.undefined_data_bytes,
            "records": len(self.records),
            "variables_used": self.variables_used,
            "pbasic": self.pbasic,
        }

    def bits(self, start: int, count: int) -> str:
        """``count`` program bits from bit address ``start`` as a 0/1 string."""
        out = []
        for b in range(start, start + count):
            byte = self.eeprom[2047 - (b >> 3)]
            out.append("1" if byte & (0x80 >> (b & 7)) else "0")
        return "".join(out)


@dataclass
class Project:
    main: str
    target: str
    slots: dict[int, SlotImage]


class _Lines:
    """Maps byte offsets of a source to 1-based (line, column); CR, LF, CR LF end a line."""

    def __init__(self, text: str) -> None:
        self.raw = text.encode("utf-8", errors="replace")
        self.starts = [0] + [m.end() for m in re.finditer(rb"\r\n|\r|\n", self.raw)]

    def position(self, offset: int) -> tuple[int, int]:
        offset = max(0, min(offset, len(self.raw)))
        line = bisect.bisect_right(self.starts, offset)
        first = self.starts[line - 1]
        return line, len(self.raw[first:offset].decode("utf-8", errors="replace")) + 1


def _position(text: str, offset: int) -> tuple[int, int]:
    return _Lines(text).position(offset)


def _source_error(text: str, filename: str, failure: Failure) -> SourceError:
    line, column = _position(text, failure.offset)
    message = failure.message
    hint = HINTS.get(failure.code)
    word = re.match(rb"[A-Za-z0-9_]+", text.encode("utf-8", "replace")[max(failure.offset, 0) :])
    name = word.group().decode("ascii").upper() if word else ""
    if name in BS2P_ONLY:
        if failure.code == 174:
            message = f"{name} is a BS2p/BS2pe instruction, not available on the BS2sx"
        hint = f"{name} exists only on the BS2p/BS2pe; use BS2sx instructions"
    return SourceError(
        message, file=filename, line=line, column=column, code=failure.code, hint=hint
    )


class _Slot(Serial, Conditional):
    pass


def _compile(text: str, directives: Directives) -> tuple[_Slot, int]:
    src = prepare(text)
    lang25 = directives.version == 250
    port = int(directives.port[3:]) if directives.port else 0xFFFF
    values = {"$STAMP": 4, "$PBASIC": directives.version, "$PORT": port}
    lexer = Lexer(src, lang25, values)
    elements = lexer.run()
    slot = _Slot(elements, lang25, lexer.number_lists, lexer.has_cc_directives)
    slot.source = src
    slot.conditional_compile()
    slot.declare_constants(K.PIN, final=False)
    slot.declare_constants(K.CON, final=False)
    slot.declare_data(final=False)
    slot.declare_constants(K.CON, final=True)
    slot.declare_constants(K.PIN, final=True)
    slot.declare_data(final=True)
    slot.declare_variables(final=False)
    slot.declare_variables(final=True)
    gosubs = 0
    for index in lexer.gosubs:
        if not slot.dead[index]:
            gosubs += 1
            if gosubs > tokens.MAX_GOSUBS:
                el = elements[index]
                raise Failure(145, el.start, el.length)
    slot.init_statements(gosubs)
    slot.idx = 0
    slot.compile_program()
    slot.patch_remaining()
    return slot, len(slot.image.records())


def tokenize_slot(
    text: str,
    filename: str,
    slot_number: int = 0,
    *,
    allow_stamp: bool = True,
) -> tuple[SlotImage, list[tuple[str, int]]]:
    """Tokenize one source; return its image and the project files its $STAMP names."""
    try:
        directives = read_directives(prepare(text), allow_stamp)
        if allow_stamp:
            if directives.target is None:
                raise Failure(156, 0)
            if directives.target != TARGET:
                raise Failure(
                    204,
                    directives.target_offset,
                    0,
                    f"bstool tokenizes for the BS2sx only, not {directives.target}",
                )
        lang25 = directives.version == 250
        slot, records = _compile(text, directives)
        if records == 0:
            raise Failure(157, 0)
    except Failure as failure:
        raise _source_error(text, filename, failure) from None
    image = slot.image
    where = _Lines(text)
    lines = [(where.position(start)[0], bit) for start, bit in slot.statement_starts]
    statements = []
    for i, (line, bit) in enumerate(lines):
        end = lines[i + 1][1] if i + 1 < len(lines) else image.pos
        statements.append((line, bit, max(end - bit, 0)))
    used_bits = slot.variables_used_bits()
    result = SlotImage(
        slot=slot_number,
        source=filename,
        eeprom=bytes(image.eeprom),
        records=image.records(),
        program_bytes=image.count(PROGRAM),
        data_bytes=image.count(DEFINED_DATA),
        undefined_data_bytes=image.count(UNDEFINED_DATA),
        variables_used=(used_bits + 7) // 8,
        variables=_variables(slot),
        pbasic="2.5" if lang25 else "2.0",
        statements=statements,
        source_lines=re.split(r"\r\n|\r|\n", text),
    )
    return result, directives.files


_VAR_SIZES = ("bit", "nib", "byte", "word")


def _variables(slot: _Slot) -> dict[str, tuple[str, int]]:
    """Where each VAR lives in RAM (for debuggers and the twin's state probes)."""
    return {
        name.upper(): (_VAR_SIZES[value >> 8 & 3], value & 0xFF)
        for name, (kind, value) in slot.symbols.items()
        if kind is K.VARIABLE
    }


def tokenize_source(
    text: str, filename: str = "<source>", files: Mapping[str, str] | None = None
) -> Project:
    """Tokenize a program given as text. Project files it names are read relative to
    ``filename``'s folder, or, with ``files`` (name -> text), taken from there instead."""
    main, names = tokenize_slot(text, filename, 0)
    slots = {0: main}
    base = Path(filename).parent
    for number, (name, offset) in enumerate(names, start=1):
        path = base / name
        try:
            if files is not None:
                if name not in files:
                    raise InputError(f"{name}: not among the sources given")
                other = files[name]
            else:
                other = read_source(path)
        except InputError as exc:
            line, column = _position(text, offset)
            raise SourceError(
                f"cannot read project file {name!r} (slot {number}): {exc.message}",
                file=filename,
                line=line,
                column=column,
                code=153,
                hint="; ".join(filter(None, [exc.hint, _PROJECT_FILES_HINT])),
            ) from None
        slots[number], _ = tokenize_slot(other, os.fspath(path), number, allow_stamp=False)
    return Project(main=filename, target="BS2sx", slots=slots)


def tokenize_file(path: str | os.PathLike[str]) -> Project:
    """Tokenize a .bsx file and every project file its $STAMP directive names."""
    return tokenize_source(read_source(path), os.fspath(path))
