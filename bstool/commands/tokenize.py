"""`bstool tokenize`: PBASIC 2.5 source -> BS2sx EEPROM images and download records."""

from __future__ import annotations

import json
from pathlib import Path

import click

from bstool import fileio
from bstool.errors import InputError
from bstool.tokenizer import Project, SlotImage, tokenize_file


def _report(project: Project, out: Path | None) -> list[str]:
    lines = [f"{project.main}: {project.target}, {len(project.slots)} slot(s)"]
    for number, slot in sorted(project.slots.items()):
        lines.append(
            f"  slot {number} ({slot.source}, PBASIC {slot.pbasic}): "
            f"program {slot.program_bytes} B, DATA {slot.data_bytes} B"
            + (f" (+{slot.undefined_data_bytes} B undefined)" if slot.undefined_data_bytes else "")
            + f", {len(slot.records)} records, variables {slot.variables_used} of 26 B"
        )
    if out is not None:
        lines.append(f"  written to {out}/slot<N>.eeprom and slot<N>.packets")
    return lines


def _listing(slot: SlotImage) -> list[str]:
    """Per statement: source line, bit address, token bits, and the source text."""
    lines = [f"slot {slot.slot}: {slot.source}", "  line   bit  bits"]
    for line, bit, count in slot.statements:
        text = slot.source_lines[line - 1].strip() if line <= len(slot.source_lines) else ""
        lines.append(f"  {line:4d} {bit:5d}  {slot.bits(bit, count)}  | {text[:60]}")
    return lines


@click.command("tokenize")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("."),
    show_default=True,
    help="Folder for slot<N>.eeprom and slot<N>.packets.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--listing", is_flag=True, help="Print each statement's bit address and bits.")
def command(source: Path, out: Path, as_json: bool, listing: bool) -> None:
    """Tokenize SOURCE (and the project files its $STAMP directive names).

    Writes, for each slot N, OUT/slotN.eeprom (2048 bytes) and OUT/slotN.packets (the
    18-byte download records in send order), then prints program bytes, DATA bytes, records
    and variables used per slot.
    """
    project = tokenize_file(source)
    try:
        for number, slot in project.slots.items():
            fileio.write_bytes(out / f"slot{number}.eeprom", slot.eeprom)
            fileio.write_bytes(out / f"slot{number}.packets", slot.packets)
    except OSError as exc:
        raise InputError(
            f"cannot write the images to {out}: {exc.strerror or exc}",
            hint="choose a writable folder with -o",
        ) from None
    if as_json:
        summary = {
            "source": project.main,
            "target": project.target,
            "out": str(out),
            "slots": {str(n): s.summary() for n, s in sorted(project.slots.items())},
        }
        click.echo(json.dumps(summary, indent=1))
    else:
        for line in _report(project, out):
            click.echo(line)
    if listing:
        for _, slot in sorted(project.slots.items()):
            for line in _listing(slot):
                click.echo(line)
