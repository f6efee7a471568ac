"""Render a module plan into PBASIC sources with the Jinja templates in templates/pbasic/."""

from __future__ import annotations

import os
from collections.abc import Iterable
from functools import lru_cache
from importlib import resources
from pathlib import Path

import jinja2

from bstool.compile import tables
from bstool.compile.plan import ModulePlan
from bstool.compile.topology import SERVO_PIN
from bstool.errors import BuildError
from bstool.wire import link

TEMPLATES = {"ca": ("ca_main.bsx.j2", "ca_rules.bsx.j2"), "nn": ("nn_main.bsx.j2", None)}


def templates_dir() -> Path:
    """Where the PBASIC templates are: ``$BSTOOL_TEMPLATES`` if set, else the package data.

    The templates live in templates/pbasic/ at the top of the repository; pyproject.toml maps
    that folder into the installed package as ``bstool.templates`` (wheel and editable alike).
    """
    override = os.environ.get("BSTOOL_TEMPLATES")
    if override:
        folder = Path(override)
        if not (folder / TEMPLATES["ca"][0]).is_file():
            raise BuildError(
                f"BSTOOL_TEMPLATES={override} holds no PBASIC templates ({TEMPLATES['ca'][0]})",
                hint="point it at a templates/pbasic folder, or unset it to use the installed ones",
            )
        return folder
    try:
        packaged = resources.files("bstool.templates") / "pbasic"
    except ModuleNotFoundError:
        packaged = None
    if packaged is not None and (packaged / TEMPLATES["ca"][0]).is_file():
        return Path(str(packaged))
    raise BuildError(
        "PBASIC templates not found in the installed package (bstool.templates/pbasic)",
        hint="reinstall bstool (pip install .), or set BSTOOL_TEMPLATES to templates/pbasic",
    )


DATA_INDENT = " " * 20


def datalines(items: Iterable[str], per_line: int, prefix: str = "") -> str:
    """DATA items, ``per_line`` to a line; a line ending in a comma continues the statement."""
    values = [prefix + item for item in items]
    rows = [", ".join(values[i : i + per_line]) for i in range(0, len(values), per_line)]
    return (",\n" + DATA_INDENT).join(rows)


def hex2(value: int) -> str:
    return f"${value:02X}"


@lru_cache(maxsize=4)
def _environment(folder: str) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(folder),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        autoescape=False,
    )
    env.filters["datalines"] = datalines
    env.filters["hex2"] = hex2
    return env


def _common(plan: ModulePlan) -> dict[str, object]:
    return {
        "p": plan,
        "servo_pin": SERVO_PIN,
        "baud": link.BAUD,
        "baudmode": link.BAUDMODE,
        "k": plan.serve,
        "q": link.ca_quiet(),  # CA: the silence clock (the manifest's link.*_quiet_units)
        "l_per_slot": tables.L_PER_SLOT,
    }


def render_module(plan: ModulePlan, *, probe: bool = False) -> dict[str, str]:
    """File name → PBASIC text: ``main.bsx`` (slot 0) and, for CA, ``rules<N>.bsx``.

    ``probe`` replaces the rule table by one byte, to measure the program alone when a slot
    does not fit.
    """
    env = _environment(str(templates_dir()))
    main_name, rules_name = TEMPLATES[plan.family]
    files = plan.slot_files
    out = {}
    ctx = _common(plan)
    out["main.bsx"] = env.get_template(main_name).render(
        ctx, project_files=files[1:], slot_title=_title(plan, 0)
    )
    if rules_name:
        for slot, data in enumerate(plan.rule_slots, start=1):
            out[files[slot]] = env.get_template(rules_name).render(
                ctx,
                project_files=[],
                slot_title=_title(plan, slot),
                base=(slot - 1) * tables.L_PER_SLOT,
                boot_slot=len(plan.rule_slots),
                data=data[:1] if probe else data,
            )
    return out


def _title(plan: ModulePlan, slot: int) -> str:
    if plan.family == "nn":
        return "Slot 0: servo, link down the leg, next state from the precomputed sum table."
    if slot == 0:
        last = len(plan.rule_slots)
        return (
            f"Slot 0: servo, neighbour links, period; slots 1-{last} hold the rule (RUN-dispatch)."
        )
    lo = (slot - 1) * tables.L_PER_SLOT
    return (
        f"Slot {slot}: rule entries for left state {lo}..{lo + tables.L_PER_SLOT - 1}; "
        "RUN 0 with the next state."
    )
