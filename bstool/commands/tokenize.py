"""`bstool tokenize`: PBASIC 2.5 source -> BS2sx EEPROM images and download records."""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Callable
from pathlib import Path

import click

from bstool import fileio, outputs
from bstool.errors import InputError
from bstool.tokenizer import Project, SlotImage, tokenize_file

MARKER = "tokenize.json"  # written last into OUT: which project the slot files belong to
MARKER_FORMAT = "bstool.slots/1"
_SLOT_FILE = re.compile(r"^slot[0-7]\.(eeprom|packets)$")


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
        lines.append(f"  written to {out}/: slot<N>.eeprom, slot<N>.packets and {MARKER}")
    return lines


def _listing(slot: SlotImage) -> list[str]:
    """Per statement: source line, bit address, token bits, and the source text."""
    lines = [f"slot {slot.slot}: {slot.source}", "  line   bit  bits"]
    for line, bit, count in slot.statements:
        text = slot.source_lines[line - 1].strip() if line <= len(slot.source_lines) else ""
        lines.append(f"  {line:4d} {bit:5d}  {slot.bits(bit, count)}  | {text[:60]}")
    return lines


def made_for(source: Path) -> Callable[[Path], bool]:
    """Whether a folder is an earlier output of ``bstool tokenize SOURCE`` (the same project):
    only slot files and the marker in it, and the marker names this main file."""

    def ours(folder: Path) -> bool:
        names = [p.name for p in folder.iterdir()]
        if MARKER not in names or not all(n == MARKER or _SLOT_FILE.match(n) for n in names):
            return False
        try:
            data = fileio.read_json(folder / MARKER, "tokenize marker")
        except InputError:
            return False
        return (
            isinstance(data, dict)
            and data.get("format") == MARKER_FORMAT
            and data.get("source") == str(source.resolve())
        )

    return ours


def default_out(source: Path) -> Path:
    return Path(f"{source.stem}.slots")


@click.command("tokenize")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for the slot files, written as a whole (default: SOURCE-NAME.slots in the "
    "current folder). It must be new, empty or an earlier output for the same SOURCE (else "
    "--force); it never replaces or holds the sources.",
)
@click.option("--force", is_flag=True, help="Replace OUT even if this command did not make it.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--listing", is_flag=True, help="Print each statement's bit address and bits.")
def command(source: Path, out: Path | None, force: bool, as_json: bool, listing: bool) -> None:
    """Tokenize SOURCE (and the project files its $STAMP directive names).

    Writes, for each slot N, OUT/slotN.eeprom (2048 bytes) and OUT/slotN.packets (the
    18-byte download records in send order), plus OUT/tokenize.json naming the project, then
    prints program bytes, DATA bytes, records and variables used per slot. The folder is
    replaced in one step: never a mix of old and new slots, no slots left of a bigger program.
    """
    out = (out if out is not None else default_out(source)).resolve()
    ours = made_for(source)
    outputs.check_dir(out, "slot folder", force=force, ours=ours, protect=(source,))
    project = tokenize_file(source)
    sources = tuple(Path(s.source) for s in project.slots.values())
    outputs.check_dir(out, "slot folder", force=force, ours=ours, protect=(source, *sources))
    marker = {
        "format": MARKER_FORMAT,
        "source": str(source.resolve()),
        "target": project.target,
        "slots": {
            str(n): {"source": s.source, "sha256": hashlib.sha256(s.eeprom).hexdigest()}
            for n, s in sorted(project.slots.items())
        },
    }
    try:
        with outputs.staged_dir(out) as tmp:
            for number, slot in sorted(project.slots.items()):
                fileio.write_bytes(tmp / f"slot{number}.eeprom", slot.eeprom)
                fileio.write_bytes(tmp / f"slot{number}.packets", slot.packets)
            fileio.write_json(tmp / MARKER, marker)
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
