"""The `#SELECT` expression, checked as Parallax checks it (issue 28 §5).

Parallax's tokenizer does not read a `#SELECT` expression with its `#IF` parser: it checks
it with the constant-expression rule of CON in its `#SELECT` variant (TOK `CompileCCSelect`
calling `ResolveConstant`; docs/tokenizer.md, "Conditional compilation"):
`term {op term}` with the CON operators, a term being a number, a #DEFINE'd name, a
directive or module name or a name declared nowhere (0), after at most one prefix operator.
Anything else where a term belongs is 225 at it. Each #CASE then compiles the expression
again with the `#IF` parser.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bstool.errors import SourceError
from bstool.tokenizer import tokenize_source

HEAD = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"
SELECT = "#SELECT "  # the expression starts in column 9


def outcome(source: str) -> tuple[int, int, int] | bytes:
    """(code, line, column) of the error, or slot 0's EEPROM image."""
    try:
        return tokenize_source(HEAD + source, "t.bsx").slots[0].eeprom
    except SourceError as exc:
        assert exc.code is not None and exc.line is not None and exc.column is not None
        return exc.code, exc.line, exc.column


def select(expression: str, cases: str = "#CASE 0\nHIGH 1\n#CASE #ELSE\nLOW 1\n") -> str:
    """A program whose third line (after the two directive lines) is `#SELECT expression`."""
    return f"{SELECT}{expression}\n{cases}#ENDSELECT\ncnt VAR Byte\nEND\n"


def test_parenthesis_is_225_at_the_parenthesis() -> None:
    """The case of the issue: bstool accepted it and then failed with 157 at 1:1."""
    assert outcome("#SELECT (1)\n#CASE 1\n#ENDSELECT\n") == (225, 3, 9)


@pytest.mark.parametrize(
    ("expression", "code", "column"),
    [
        # 225: something that is not a term where a term belongs
        ("(1)", 225, 9),
        ("-(1)", 225, 10),
        ("1 + (2)", 225, 13),
        ("1 +", 225, 12),  # a missing operand: at the line end
        ("2 * 3 -", 225, 16),
        ("", 225, 9),
        ("- -1", 225, 11),  # one prefix operator only
        ("~1", 225, 9),  # unary operators, NOT, variables, keywords are no terms
        ("ABS 1", 225, 9),
        ("NOT 1", 225, 9),
        ("B0", 225, 9),  # the #IF parser says 195 for a variable
        ("1 + W3", 225, 13),
        ("HIGH", 225, 9),
        ("DEC", 225, 9),
        ("1 + ,", 225, 13),
        # the expression stops before anything but a CON operator; then the line must end
        ("1 2", 129, 11),
        ("1 = 1", 129, 11),
        ("1 <> 1", 129, 11),
        ("1 MIN 2", 129, 11),
        ("1 // 2", 129, 11),
        ("1 AND 1", 129, 11),
        ("1)", 129, 10),
        ("1, 2", 129, 10),
        # a name CON/VAR/PIN/DATA declare; dividing by a term worth 0 (at the term)
        ("cnt", 195, 9),
        ("1 + cnt", 195, 13),
        ("1 / 0", 113, 13),
        ("4 / Nowhere", 113, 13),  # a name declared nowhere is 0
        ("4 / -0", 113, 14),
        # a prefix operator other than '-' passes the check; the #CASE's parse rejects it
        ("* 2", 188, 9),
        ("1 + * 2", 188, 13),
    ],
)
def test_select_expression_errors(expression: str, code: int, column: int) -> None:
    assert outcome(select(expression)) == (code, 3, column)


@pytest.mark.parametrize(
    "expression",
    [
        "0",
        "Nowhere",
        "-0",
        "5 - 5",
        "-1 + 1",
        "1 - -1 - 2",
        "$STAMP - $STAMP",
        "BS2SX - 4",
        "1 << 2 >> 1 * 3 / 2 - 3 | 0 ^ 0 & 7",
    ],
)
def test_accepted_expressions_pick_their_case(expression: str) -> None:
    """Each is worth 0, so `#CASE 0` (HIGH 1) is taken."""
    assert outcome(select(expression)) == outcome("HIGH 1\ncnt VAR Byte\nEND\n")


def test_other_prefix_operator_passes_when_no_case_compiles_the_expression() -> None:
    """`#CASE #ELSE` compiles no test, so nothing parses `* 2` with the #IF parser."""
    assert outcome(select("* 2", "#CASE #ELSE\nLOW 1\n")) == outcome("LOW 1\nEND\n")


def test_line_end_and_case_are_checked_after_the_expression() -> None:
    assert outcome(f"{SELECT}1 MIN 2\nHIGH 1\n") == (129, 3, 11)
    assert outcome(f"{SELECT}* 2\nHIGH 1\n#ENDSELECT\n") == (219, 4, 1)


# ---- property: random #SELECT lines against the rule ----------------------------------------
# terms with their values (each `#DEFINE`d below, or a number, a module name, a name that is
# declared nowhere)
DEFINES = "#DEFINE Lvl = 3\n#DEFINE Flag\n#DEFINE Zero = 0\n"
TERMS = {"0": 0, "1": 1, "7": 7, "300": 300, "$FF": 255, "%101": 5, "Lvl": 3, "Flag": 0xFFFF,
         "Zero": 0, "Nowhere": 0, "BS2SX": 4}  # fmt: skip
SMALL = ["0", "1", "7", "Lvl"]  # shift counts
OPS = {
    "+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
    "/": lambda a, b: a // b, "<<": lambda a, b: a << b, ">>": lambda a, b: a >> b,
    "&": lambda a, b: a & b, "|": lambda a, b: a | b, "^": lambda a, b: a ^ b,
}  # fmt: skip
BAD = {"(": 225, "~": 225, "NOT": 225, "B0": 225, "HIGH": 225, "cnt": 195}
EXAMPLES = int(os.environ.get("BSTOOL_GRAMMAR_EXAMPLES", "50"))


@st.composite
def select_lines(draw: st.DrawFn) -> tuple[str, tuple[int, int, int] | int]:
    """A #SELECT expression and what it must give: (code, line, column) or its value."""
    count = draw(st.integers(1, 5))
    bad_at = draw(st.one_of(st.none(), st.integers(0, count - 1)))
    missing_last = draw(st.booleans()) and count > 1  # end the line after an operator
    tokens: list[str] = []
    column = 9
    line = 3 + DEFINES.count("\n")
    value = 0
    expected: tuple[int, int, int] | int | None = None
    op = "+"

    def put(text: str) -> int:
        nonlocal column
        start = column
        tokens.append(text)
        column += len(text) + 1
        return start

    for i in range(count):
        if i:
            op = draw(st.sampled_from(sorted(OPS)))
            put(op)
        if missing_last and i == count - 1:
            if expected is None:
                expected = (225, line, column - 1)  # the line end, right after the operator
            break
        shift = op in ("<<", ">>")
        if not shift and draw(st.booleans()):
            put("-")
            negative = True
        else:
            negative = False
        if i == bad_at:
            name = draw(st.sampled_from(sorted(BAD)))
            start = put(name)
            if expected is None:
                expected = (BAD[name], line, start)
            continue
        name = draw(st.sampled_from(SMALL if shift else sorted(TERMS)))
        start = put(name)
        term = -TERMS[name] & 0xFFFF if negative else TERMS[name]
        if op == "/" and term == 0 and expected is None:
            expected = (113, line, start)
        if expected is None:
            value = OPS[op](value, term) & 0xFFFF
    return " ".join(tokens), value if expected is None else expected


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(select_lines())
def test_select_lines_follow_the_constant_rule(
    case: tuple[str, tuple[int, int, int] | int],
) -> None:
    """Accepted lines take the #CASE of their left-to-right 16-bit value; a non-term, a
    declared name or a zero divisor is the error the rule names, at that element."""
    expression, expected = case
    value = expected if isinstance(expected, int) else 0
    source = (
        f"{DEFINES}{SELECT}{expression}\n#CASE {value}\nHIGH 1\n#CASE #ELSE\nLOW 1\n"
        "#ENDSELECT\ncnt VAR Byte\nEND\n"
    )
    if isinstance(expected, int):
        assert outcome(source) == outcome("HIGH 1\nEND\n")
    else:
        assert outcome(source) == expected
