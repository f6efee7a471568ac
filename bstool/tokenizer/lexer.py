"""Source text -> element list (the tokenizer's words), and the editor directives.

An element is one word of the program: a reserved word, a user symbol, a number, an operator
or punctuation, or an end of statement. Positions are character offsets into the source so
errors can point at the exact place. Rules of the PBASIC 2.5 editor/tokenizer that matter
for byte-exact output:

* every control character (other than TAB) ends a line; CR LF therefore ends two lines, which
  is harmless because consecutive ends collapse into one;
* a string "abc" becomes the constants 'a' , 'b' , 'c' (separated by commas);
* in PBASIC 2.5 an end of line right after a comma is ignored (line continuation), even with
  a comment between;
* two-character operators may have blanks between their characters (``< =``);
* numbers are decimal, $hex or %binary; symbols are at most 32 characters, case-insensitive.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import IntEnum

from bstool.tokenizer import tokens
from bstool.tokenizer.diagnostics import Failure

ETX = 3  # every line end becomes this marker
_SYMBOL_TAIL = re.compile(rb"[A-Za-z0-9_]*")
_BLANKS = re.compile(rb"[\x00\t ]+")
_FAST = re.compile(
    rb"(?P<b>[\t ]+)|(?P<c>,)|(?P<h>\$[0-9A-Fa-f]{1,4})(?![0-9A-Za-z_])"
    rb"|(?P<d>[0-9]{1,5})(?![0-9])|(?P<s>[A-Za-z_][A-Za-z0-9_]{0,31})(?![A-Za-z0-9_])"
)


class K(IntEnum):
    """Element kinds."""

    DIRECTIVE = 0
    TARGET = 1
    CCDIRECTIVE = 2
    INSTRUCTION = 3
    CON = 4
    VARIABLE = 5
    VARTYPE = 6
    VARMOD = 7
    ANYNUM_IO = 8
    COND1 = 9
    BINOP = 10
    UNOP = 11
    CONST = 12
    PERIOD = 13
    COMMA = 14
    QUESTION = 15
    BACKSLASH = 16
    AT = 17
    LPAREN = 18
    LBRACKET = 19
    RCURLY = 20
    CCTHEN = 21
    DATA = 22
    STEP = 23
    TO = 24
    THEN = 25
    WHILE = 26
    UNTIL = 27
    PIN = 28
    VAR = 29
    ASC_IO = 30
    NUM_IO = 31
    REP_IO = 32
    SKIP_IO = 33
    SPSTR_IO = 34
    STR_IO = 35
    WAIT_IO = 36
    WAITSTR_IO = 37
    COND2 = 38
    COND3 = 39
    RPAREN = 40
    RBRACKET = 41
    PINNUM = 42
    LABEL = 43
    CCCONST = 44
    FILENAME = 45
    UNDEF = 46
    END = 47
    CANCEL = 48


# Operator numbers used by the expression compiler: unary 0-7, binary 8-$19, comparisons
# $1A-$1F (the same numbers as the expression items of tokens.Unary / tokens.Binary).
OP_SUB = int(tokens.Binary.SUB)
OP_NEG = int(tokens.Unary.NEG)
OP_EQ = int(tokens.Binary.EQ)

INSTRUCTIONS_COMMON = (
    "FOR", "NEXT", "GOTO", "GOSUB", "RETURN", "IF", "BRANCH", "LOOKUP", "LOOKDOWN", "RANDOM",
    "READ", "WRITE", "PAUSE", "INPUT", "OUTPUT", "LOW", "HIGH", "TOGGLE", "REVERSE", "SEROUT",
    "SERIN", "PULSOUT", "PULSIN", "COUNT", "SHIFTOUT", "SHIFTIN", "RCTIME", "BUTTON", "PWM",
    "FREQOUT", "DTMFOUT", "XOUT", "DEBUG", "STOP", "NAP", "SLEEP", "END", "GET", "PUT", "RUN",
)  # fmt: skip
INSTRUCTIONS_25 = (
    "DO", "EXIT", "LOOP", "ELSE", "ELSEIF", "ENDIF", "SELECT", "CASE", "ENDSELECT", "ON",
    "DEBUGIN",
)  # fmt: skip
# BS2p/BS2pe-only words: ordinary symbols on the BS2sx (used to explain error 174).
BS2P_ONLY = frozenset((
    "LCDIN", "LCDOUT", "LCDCMD", "I2CIN", "I2COUT", "POLLIN", "POLLOUT", "OWIN", "OWOUT",
    "IOTERM", "STORE", "POLLWAIT", "POLLRUN", "MAINIO", "AUXIO", "POLLMODE", "SPSTR",
))  # fmt: skip


def _reserved(lang25: bool) -> dict[str, tuple[K, int | str]]:
    words: dict[str, tuple[K, int | str]] = {}
    for table, size in (
        (tokens.BIT_REGISTERS, tokens.VarSize.BIT),
        (tokens.NIB_REGISTERS, tokens.VarSize.NIB),
        (tokens.BYTE_REGISTERS, tokens.VarSize.BYTE),
        (tokens.WORD_REGISTERS, tokens.VarSize.WORD),
    ):
        for name, index in table.items():
            words[name] = (K.VARIABLE, int(size) << 8 | index)
    words.update({"CON": (K.CON, 0), "DATA": (K.DATA, 0), "VAR": (K.VAR, 0)})
    for name in INSTRUCTIONS_COMMON:
        words[name] = (K.INSTRUCTION, name)
    words.update({"$STAMP": (K.DIRECTIVE, 0), "$PORT": (K.DIRECTIVE, 1)})
    words["$PBASIC"] = (K.DIRECTIVE, 2)
    for i, name in enumerate(("BS2", "BS2E", "BS2SX", "BS2P", "BS2PE")):
        words[name] = (K.TARGET, 2 + i)
    words.update({"TO": (K.TO, 0), "STEP": (K.STEP, 0), "THEN": (K.THEN, 0)})
    for op in tokens.Unary:
        if op is not tokens.Unary.NEG:
            words["~" if op is tokens.Unary.NOT else op.name] = (K.UNOP, int(op))
    symbols = {"AND": "&", "OR": "|", "XOR": "^", "ADD": "+", "SUB": "-", "MULMID": "*/"}
    symbols.update({"MUL": "*", "MULHIGH": "**", "MOD": "//", "DIV": "/", "SHL": "<<"})
    symbols["SHR"] = ">>"
    for bop in tokens.Binary:
        if bop < tokens.Binary.GE:
            words[symbols.get(bop.name, bop.name)] = (K.BINOP, int(bop))
    for spelling, cmp in (
        ("=>", "GE"), (">=", "GE"), ("<=", "LE"), ("=<", "LE"), ("=", "EQ"), ("<>", "NE"),
        ("><", "NE"), (">", "GT"), ("<", "LT"),
    ):  # fmt: skip
        words[spelling] = (K.COND1, int(tokens.Binary[cmp]))
    for name in ("AND", "OR", "XOR"):
        words[name] = (K.COND2, int(tokens.Binary[name]))
    words["NOT"] = (K.COND3, int(tokens.Unary.NOT))
    for size in tokens.VarSize:
        words[size.name] = (K.VARTYPE, int(size))
    for name, (msize, part) in tokens.VARIABLE_MODIFIERS.items():
        words[name] = (K.VARMOD, int(msize) << 8 | (0x80 if part is None else part))
    io = {"ASC": K.ASC_IO, "STR": K.STR_IO, "REP": K.REP_IO, "SKIP": K.SKIP_IO}
    io.update({"WAITSTR": K.WAITSTR_IO, "WAIT": K.WAIT_IO})
    words.update({name: (kind, 0) for name, kind in io.items()})
    words.update({n: (K.ANYNUM_IO, v) for n, v in tokens.ANY_NUMBER_FORMATTERS.items()})
    words.update({n: (K.NUM_IO, v) for n, v in tokens.NUMBER_FORMATTERS.items()})
    for text, kind in (
        (".", K.PERIOD), ("?", K.QUESTION), ("\\", K.BACKSLASH), ("@", K.AT),
        ("(", K.LPAREN), (")", K.RPAREN), ("[", K.LBRACKET), ("]", K.RBRACKET),
    ):  # fmt: skip
        words[text] = (kind, 0)
    words.update({n: (K.CONST, v) for n, v in tokens.BUILTIN_CONSTANTS.items()})
    if lang25:
        words["PIN"] = (K.PIN, 0)
        for name in INSTRUCTIONS_25:
            words[name] = (K.INSTRUCTION, name)
        words.update({"UNTIL": (K.UNTIL, 0), "WHILE": (K.WHILE, 0)})
        for name in ("#DEFINE", "#ERROR", "#IF", "#ELSE", "#ENDIF", "#SELECT", "#CASE"):
            words[name] = (K.CCDIRECTIVE, name[1:])
        words["#ENDSELECT"] = (K.CCDIRECTIVE, "ENDSELECT")
        words["#THEN"] = (K.CCTHEN, 0)
        words.update({n: (K.CONST, v) for n, v in tokens.BUILTIN_CONSTANTS_25.items()})
    return words


RESERVED = {False: _reserved(False), True: _reserved(True)}


@dataclass(slots=True)
class Element:
    kind: K
    value: int | str
    start: int
    length: int
    name: str = ""  # upper-cased spelling of a symbol (user symbols are looked up late)
    soft: bool = False  # for END: ':' (True) or end of line / comment (False)


_TO_ETX = bytes(ETX if (c < 32 and c != 9) else c for c in range(256))
MAX_ELEMENTS = 10240  # the IDE's element list holds this many; one more is error 107
MAX_NUMBER_CHARS = 16  # digits (and '.') a number may have; the 17th is error 108
MAX_SYMBOL_CHARS = 32
_NUMBER_RUNS = {
    2: re.compile(rb"[01]+"),
    10: re.compile(rb"[0-9]+"),
    16: re.compile(rb"[0-9A-Fa-f]+"),
}
_VERSION_RUN = re.compile(rb"[0-9.]+")  # a decimal number that may hold a point (2.5)
# An operator of two characters (blanks between them are allowed: "< =").
_OPERATOR_PAIR = re.compile(rb"([*/<>=])[\t ]*([*/<>=])")
# ", 12, $3F, 6" up to (not including) what follows the last number: the bulk of DATA tables.
# Every number must be followed by another comma, the end of the line or a comment. In
# PBASIC 2.5 a comma continues the statement on the next line (comments between allowed).
_LIST_NUMBER = rb"(?:[0-9]{1,5}|\$[0-9A-Fa-f]{1,4})"
_LIST_GAP = {False: rb"[\t ]*", True: rb"(?:[\t \x03]|'[^\x03]*\x03)*"}
_NUMBER_LIST = {
    lang25: re.compile(
        rb"," + gap + _LIST_NUMBER + rb"(?:[\t ]*," + gap + _LIST_NUMBER + rb")*(?=[\t ]*[,\x03'])"
    )
    for lang25, gap in _LIST_GAP.items()
}
_LIST_ITEM = re.compile(rb",(?:[\t \x03]|'[^\x03]*\x03)*([0-9]+|\$[0-9A-Fa-f]+)")


def prepare(text: str) -> bytearray:
    """Source characters as bytes, every control character except TAB turned into ETX."""
    out = bytearray(text.encode("utf-8", errors="replace").translate(_TO_ETX))
    out.append(ETX)
    return out


def _is_symbol_char(c: int) -> bool:
    return c == 95 or 48 <= c <= 57 or 65 <= c <= 90 or 97 <= c <= 122


def _is_symbol_start(c: int) -> bool:
    return c == 95 or 65 <= c <= 90 or 97 <= c <= 122


def read_number(
    src: bytes | bytearray, pos: int, base: int, start: int, decimals: int = 0
) -> tuple[int, int]:
    """Value of the number whose first digit is at ``pos`` and the position after it.

    ``start`` is where the number's element begins (its ``$``/``%`` prefix, if any). With
    ``decimals`` > 0 (only for ``$PBASIC 2.5``) a decimal point is allowed and the value is
    scaled to that many places: "2.5" -> 250, "2" -> 200.

    The IDE reads at most 17 characters and stops reading as soon as the value has passed 16
    bits; what it read then decides the error: too big (109) wins over too long (108).
    """
    run = (_VERSION_RUN if decimals else _NUMBER_RUNS[base]).match(src, pos)
    if run is None or run.group()[:1] == b".":
        raise Failure(105 if base == 2 else 104, start + 1)
    text = run.group()[: MAX_NUMBER_CHARS + 1]
    whole, point, _ = text.partition(b".")
    if point and int(whole, base) == 0:
        raise Failure(186, start)  # "0.5": a version number below 1
    # the shortest prefix that no longer fits 16 bits is where the IDE stopped reading
    read = next(
        (
            n
            for n in range(1, len(text) + 1)
            if int(b"0" + text[:n].replace(b".", b""), base) > 0xFFFF
        ),
        len(text),
    )
    text = text[:read]
    value = int(text.replace(b".", b""), base)
    if decimals:
        fraction = len(text) - text.index(b".") if b"." in text else 1
        value *= base ** max(decimals + 1 - fraction, 0)
    if value > 0xFFFF:
        raise Failure(109, start)
    if len(text) > MAX_NUMBER_CHARS:
        raise Failure(108, start)
    return value, pos + len(text)


@dataclass
class Lexer:
    """Turns one prepared source into elements (the second, full pass)."""

    src: bytearray
    lang25: bool
    # values of $STAMP, $PBASIC and $PORT when used as constants (CON, #IF ...)
    directive_values: dict[str, int] = field(default_factory=dict)
    elements: list[Element] = field(default_factory=list)
    # element index of each bulk-read number list -> index just past it (see _number_list)
    number_lists: dict[int, int] = field(default_factory=dict)
    has_cc_directives: bool = False
    gosubs: list[int] = field(default_factory=list)  # element indices of GOSUB
    # True where a statement end would add nothing: right after an end, or (PBASIC 2.5) after
    # a comma, which continues the statement on the next line.
    _end_is_redundant: bool = True

    def _add(self, kind: K, value: int | str, start: int, pos: int, name: str = "") -> None:
        elements = self.elements
        if len(elements) >= MAX_ELEMENTS:
            raise Failure(107, start)
        elements.append(Element(kind, value, start, pos - start, name))
        self._end_is_redundant = False

    def _end(self, start: int, pos: int, soft: bool = False) -> None:
        if not self._end_is_redundant:
            self._add(K.END, 1 if soft else 0, start, pos)
            self.elements[-1].soft = soft
            self._end_is_redundant = True

    def _comma(self, start: int) -> None:
        self._add(K.COMMA, 0, start, start + 1)
        self._end_is_redundant = self.lang25

    def number(self, pos: int, base: int, start: int, decimals: int = 0) -> tuple[int, int]:
        """Read a number whose first digit is at ``pos``; return (value, position after)."""
        return read_number(self.src, pos, base, start, decimals)

    def symbol(self, pos: int) -> tuple[str, int]:
        """Read a symbol whose first character was at ``pos - 1``."""
        start = pos - 1
        m = _SYMBOL_TAIL.match(self.src, pos)
        end = m.end() if m else pos
        if end - start > MAX_SYMBOL_CHARS:
            raise Failure(106, start)
        return self.src[start:end].decode("latin-1").upper(), end

    def _symbol_element(self, name: str, start: int, pos: int) -> None:
        kind, value = RESERVED[self.lang25].get(name, (K.UNDEF, 0))
        if kind is K.DIRECTIVE:
            value = self.directive_values.get(name, 0)
        elif kind is K.CCDIRECTIVE:
            self.has_cc_directives = True
        elif value == "GOSUB":
            self.gosubs.append(len(self.elements))
        self._add(kind, value, start, pos, name)

    def _string(self, quote: int) -> tuple[int, int]:
        """A string literal: "abc" is the list 'a', 'b', 'c' (each character a constant).

        The first character's element starts at the opening quote; each comma sits on the
        character it precedes. Returns the position after the closing quote and the start of
        the last character's element (where an end of source is reported).
        """
        src = self.src
        first = quote + 1
        close = src.find(b'"', first)
        line_end = src.index(ETX, first)
        if close == first:
            raise Failure(101, quote, 2)
        closed = 0 <= close < line_end
        stop = close if closed else line_end
        for at in range(first, stop):
            self._add(K.CONST, src[at], quote if at == first else at, at + 1)
            if at + 1 < stop or not closed:
                self._comma(at + 1)
        if not closed:
            raise Failure(102, quote if stop == first else stop)
        return close + 1, quote if stop - first == 1 else stop - 1

    def _number_list(self, pos: int) -> int:
        """Bulk path for ", n, $n, n" (DATA tables): the same elements, built in one go.

        Returns the position after the last number taken, or ``pos`` when the text there is
        not such a list. A number over 16 bits ends the run before its comma (the general path
        then reports it); a run that would overflow the element list fails at the first
        element that does not fit, as the general path would. Either way the text of the run
        is looked at once, so a long table costs time in proportion to its length.
        """
        m = _NUMBER_LIST[self.lang25].match(self.src, pos)
        if m is None:
            return pos
        comma, const = K.COMMA, K.CONST
        elements = self.elements
        room = MAX_ELEMENTS - len(elements)
        built: list[Element] = []
        add = built.append
        end = m.end()
        for item in _LIST_ITEM.finditer(m.group()):
            number = item.group(1)
            value = int(number[1:], 16) if number[0] == 36 else int(number)
            if value > 0xFFFF:
                end = pos + item.start()  # the general path reads from this comma on
                break
            if len(built) + 2 > room:
                elements += built
                at = pos + item.start()
                raise Failure(107, at if len(built) == room else pos + item.start(1))
            add(Element(comma, 0, pos + item.start(), 1))
            add(Element(const, value, pos + item.start(1), len(number)))
        if not built:
            return pos
        self.number_lists[len(elements)] = len(elements) + len(built)
        elements += built
        self._end_is_redundant = False
        return end

    def run(self) -> list[Element]:
        """Scan the whole source; return the elements."""
        src = self.src
        size = len(src) - 1
        pos = start = 0
        reserved = RESERVED[self.lang25]
        fast = _FAST.match
        while pos < size:
            if src[pos] == 44:  # ','
                after = self._number_list(pos)
                if after != pos:
                    start = self.elements[-1].start
                    pos = after
                    continue
            m = fast(src, pos)
            if m is not None:  # blanks, ',', short numbers and symbols: the common cases
                group, end = m.lastgroup, m.end()
                if group == "b":
                    start, pos = end - 1, end
                    continue
                start = pos
                if group == "c":
                    self._comma(start)
                elif group == "s":
                    self._symbol_element(src[start:end].decode("latin-1").upper(), start, end)
                else:
                    digits = src[start + 1 : end] if group == "h" else src[start:end]
                    value = int(digits, 16 if group == "h" else 10)
                    if value > 0xFFFF:
                        value, end = self.number(start, 10, start)
                    self._add(K.CONST, value, start, end)
                pos = end
                continue
            start = pos
            c = src[pos]
            pos += 1
            if c == ETX:
                self._end(start, pos)
            elif c in (0, 9, 32):
                m = _BLANKS.match(src, pos)
                if m and m.end() > pos:
                    start, pos = m.end() - 1, m.end()
            elif c == 44:  # ,
                self._comma(start)
            elif c == 58:  # : ends a statement even right after another end
                self._end_is_redundant = False
                self._end(start, pos, soft=True)
            elif c == 39:  # ' comment
                self._end(start, pos)
                pos = src.index(ETX, pos) + 1
            elif c == 34:  # "
                pos, start = self._string(start)
            elif c == 37:  # %
                value, pos = self.number(pos, 2, start)
                self._add(K.CONST, value, start, pos)
            elif c == 36:  # $: a directive name in 2.5, else a hex number
                name = ""
                if self.lang25:
                    m = _SYMBOL_TAIL.match(src, pos)
                    end = m.end() if m else pos
                    if end - start > MAX_SYMBOL_CHARS:
                        raise Failure(106, start)
                    if end > pos and src[pos] in b"PSps":  # $PBASIC, $PORT, $STAMP
                        name = src[start:end].decode("latin-1").upper()
                if name in reserved:
                    self._symbol_element(name, start, end)
                    pos = end
                else:
                    value, pos = self.number(pos, 16, start)
                    self._add(K.CONST, value, start, pos)
            elif 48 <= c <= 57:
                value, pos = self.number(pos - 1, 10, start)
                self._add(K.CONST, value, start, pos)
            elif c == 35:  # #
                if not self.lang25:
                    raise Failure(103, start)
                name, pos = self.symbol(pos)
                if name not in reserved:
                    raise Failure(154, start)
                self._symbol_element(name, start, pos)
            elif _is_symbol_start(c):
                name, pos = self.symbol(pos)
                self._symbol_element(name, start, pos)
            else:
                pos = self._operator(start)
        elements = self.elements
        if not self._end_is_redundant or not elements or elements[-1].kind is K.END:
            self._end(start, pos)
        else:
            # the source ends in a continuation comma: its statement still ends, one column
            # past the comma
            at = elements[-1].start + elements[-1].length + 1
            self._end_is_redundant = False
            self._end(at, at + 1)
        return elements

    def _operator(self, start: int) -> int:
        """An operator or punctuation mark at ``start``; two-character ones are tried first."""
        reserved = RESERVED[self.lang25]
        pair = _OPERATOR_PAIR.match(self.src, start)
        if pair is not None:
            spelling = (pair.group(1) + pair.group(2)).decode("ascii")
            if spelling in reserved:
                kind, value = reserved[spelling]
                self._add(kind, value, start, pair.end(), spelling)
                return pair.end()
        c = self.src[start]
        single = chr(c) if c < 128 else ""
        if single in reserved:
            kind, value = reserved[single]
            self._add(kind, value, start, start + 1, single)
            return start + 1
        raise Failure(103, start)


# ---- editor directives: ' {$STAMP BS2sx, file, ...}  ' {$PBASIC 2.5}  ' {$PORT COM1} ------


def _is_path_char(c: int, quoted: bool) -> bool:
    if c in (33, 43, 61, 126) or 35 <= c <= 41 or 45 <= c <= 59 or 64 <= c <= 122:
        return True
    return quoted and c in (32, 44, 123, 125)


@dataclass
class Directives:
    target: str | None = None
    target_offset: int = 0
    files: list[tuple[str, int]] = field(default_factory=list)  # (name, offset)
    version: int = 200
    version_offset: int = 0
    port: str | None = None
    stamp_seen: bool = False


def _directive_tokens(src: bytearray, pos: int) -> list[tuple[str, str, int]]:
    """Tokens of one directive starting at the '$'; each is (kind, text, offset).

    The first two words ($STAMP and the module name) are symbols; after them, unquoted text
    is a project file name (``{$STAMP BS2sx, a.bsx, sub/b.bsx}``).
    """
    out: list[tuple[str, str, int]] = []
    words = 0  # directive names and symbols read so far
    lex = Lexer(src, True)
    while True:
        start = pos
        c = src[pos]
        pos += 1
        if c == ETX:
            out.append(("end", "", start))
            return out
        if c in (0, 9, 32):
            continue
        if c == 44:
            out.append((",", ",", start))
        elif c == 125:
            out.append(("}", "}", start))
            return out
        elif c == 34:
            begin = pos
            if src[pos] == 34:
                raise Failure(101, begin, 1)
            while _is_path_char(src[pos], True):
                pos += 1
            if src[pos] != 34:
                raise Failure(102, begin)
            out.append(("file", src[begin:pos].decode("utf-8", "replace"), begin))
            pos += 1
        elif c == 36:
            name, pos = lex.symbol(pos)
            words += 1
            if name not in ("$STAMP", "$PORT", "$PBASIC"):
                raise Failure(154, start)
            out.append(("directive", name, start))
        elif 48 <= c <= 57:
            value, pos = lex.number(pos - 1, 10, start, decimals=2)
            out.append(("number", str(value), start))
        elif _is_symbol_char(c) and words < 2:
            name, pos = lex.symbol(pos)
            words += 1
            out.append(("symbol", name, start))
        elif _is_path_char(c, False) and words >= 2:
            while _is_path_char(src[pos], False):
                pos += 1
            out.append(("file", src[start:pos].decode("utf-8", "replace"), start))
        else:
            raise Failure(103, start)


def read_directives(src: bytearray, allow_stamp: bool) -> Directives:
    """Find and check the editor directives (they live in comments)."""
    found = Directives()
    size = len(src) - 1
    pos = 0
    while pos < size:
        pos = src.find(b"'", pos)
        if pos < 0 or pos >= size:
            break
        pos += 1
        while src[pos] in (9, 32):
            pos += 1
        if src[pos] == 123:
            pos += 1
            while src[pos] in (9, 32):
                pos += 1
            if src[pos] == 36:
                _apply_directive(found, _directive_tokens(src, pos), allow_stamp)
        pos = src.index(ETX, pos)
    return found


def _apply_directive(found: Directives, toks: list[tuple[str, str, int]], allow: bool) -> None:
    _, name, offset = toks[0]
    rest = [*toks[1:], ("end", "", toks[-1][2])]
    if name == "$STAMP":
        if not allow:
            return
        if found.stamp_seen:
            raise Failure(155, offset)
        found.stamp_seen = True
        k, text, off = rest[0]
        if k != "symbol" or text not in ("BS2", "BS2E", "BS2SX", "BS2P", "BS2PE"):
            raise Failure(204, off)
        found.target, found.target_offset = text, off
        i = 1
        if text != "BS2":
            while rest[i][0] == ",":
                if len(found.files) > 6:
                    raise Failure(203, rest[i][2])
                k, fname, off = rest[i + 1]
                if k != "file":
                    raise Failure(153, off)
                found.files.append((fname, off))
                i += 2
        if rest[i][0] != "}":
            raise Failure(201, rest[i][2])
    elif name == "$PBASIC":
        if found.version_offset:
            raise Failure(155, offset)
        k, text, off = rest[0]
        if k != "number":
            raise Failure(112, off)
        if text not in ("200", "250"):
            raise Failure(187, off)
        found.version, found.version_offset = int(text), off
        if rest[1][0] != "}":
            raise Failure(201, rest[1][2])
    elif name == "$PORT":
        if found.port is not None:
            raise Failure(155, offset)
        k, text, off = rest[0]
        if k != "symbol" or len(text) < 4 or not text.startswith("COM") or not text[3:].isdigit():
            raise Failure(208, off)
        found.port = text
        if rest[1][0] != "}":
            raise Failure(201, rest[1][2])
