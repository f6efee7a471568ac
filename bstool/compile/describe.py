"""The build's descriptions: its manifest (bstool.buildfile, bstool.build/1) and WIRING.md."""

from __future__ import annotations

import hashlib

from bstool import buildfile as bf
from bstool.compile.results import ModuleResult, SlotResult
from bstool.compile.timing import PAD_PIN
from bstool.compile.topology import SERVO_PIN, links, pin_role
from bstool.controllers import NN_MODELS, Controller
from bstool.wire import announce, link

RAM_BYTES = 26


def _flash_slots(res: ModuleResult) -> list[int]:
    """Rule slots first, slot 0 last: slot 0 starts running as soon as it is written."""
    return [*(s.slot for s in reversed(res.slots[1:])), 0]


def _slot(d: str, sr: SlotResult) -> bf.Slot:
    if sr.eeprom is None:
        return bf.Slot(sr.slot, f"{d}/{sr.file}", sr.source_sha256, sr.program_bytes, sr.data_bytes)
    return bf.Slot(
        sr.slot,
        f"{d}/{sr.file}",
        sr.source_sha256,
        sr.program_bytes,
        sr.data_bytes,
        eeprom=f"{d}/slot{sr.slot}.eeprom",
        packets=f"{d}/slot{sr.slot}.packets",
        sha256=hashlib.sha256(sr.eeprom).hexdigest(),
    )


def _module(ctrl: Controller, res: ModuleResult) -> bf.Module:
    p = res.plan
    d = f"modules/{p.dirname}"
    pins = [bf.Pin(SERVO_PIN, "servo"), bf.Pin(PAD_PIN, "pad")]
    for ll in p.links:
        pins.append(
            bf.Pin(
                pin=ll.pin,
                use="link",
                port=pin_role(ctrl.model, ctrl.legs, ctrl.modules, p.mid, ll.peer),
                neighbour=ll.peer,
                neighbour_pin=ll.link.pin(ll.peer),
                role="master" if ll.master else "slave",
                colour=ll.link.colour,
                deadline_ms=ll.deadline,
                first_deadline_ms=ll.first_deadline,
                miss_iteration_ms=ll.iter_ms,
                ok_iteration_ms=ll.ok_ms,
                recover_ms=None if ll.master else ll.recover_ms,
                bypass=ll.link.bypass,
                near_deadline_ms=ll.near_deadline or None,
                send_states=len(ll.send),
                receive_states=len(ll.store),
                wait_base_units=ll.wait_units,
            )
        )
    return bf.Module(
        module=p.mid,
        label=p.label,
        dir=d,
        entry=f"{d}/main.bsx",
        initial_state=p.r0,
        slots=[_slot(d, sr) for sr in res.slots],
        ram_bytes=res.ram_bytes,
        ram_bytes_available=RAM_BYTES,
        pins=pins,
        servo=bf.ServoTable(list(p.pulses), list(p.clipped)),
        transition_ms=p.hold_ms,
        exchange_allowance_ms=p.exch_ms,
        free_exchange_ms=p.free_ms,
        hold_step_ms=p.hold_step,
        hold_pause_ms=p.hold_pause,
        pad_base=p.pad_base,
        roll_call_ms=p.roll_ms,
        timing=bf.Timing(**res.timing),
        ram_map=res.ram_map or None,
    )


def manifest(
    ctrl: Controller,
    source: str,
    full_hash: str,
    period: float,
    results: list[ModuleResult],
    tokenized: bool,
) -> bf.Manifest:
    """The build's manifest (bstool.build/1) for ``results``."""
    wires = [
        bf.Wire(lk.master, lk.master_pin, lk.slave, lk.slave_pin, lk.colour, lk.bypass)
        for lk in links(ctrl.model, ctrl.legs, ctrl.modules)
    ]
    order = [
        bf.FlashStep(res.plan.mid, _flash_slots(res))
        for res in sorted(results, key=lambda r: r.plan.mid)
    ]
    return bf.Manifest(
        controller=bf.ControllerInfo(
            file=source,
            copy=bf.CONTROLLER_FILE,
            hash=full_hash,
            hash8=full_hash[:8],
            model=ctrl.model,
        ),
        robot=bf.RobotSize(ctrl.legs, ctrl.modules, ctrl.k),
        period_s=period,
        tokenized=tokenized,
        link=bf.LinkSettings(
            protocol="protocol/link.md",
            baud=link.BAUD,
            baudmode=link.BAUDMODE,
            request_base=link.REQUEST_BASE,
            reply_base=link.REPLY_BASE,
            reply_base_units=link.REPLY_BASE_UNITS,
            recover_units=link.RECOVER_UNITS,
            linger_units=link.LINGER_UNITS,
            linger_listens=link.LINGER_LISTENS,
            silent_transitions=link.SILENT_TRANSITIONS,
            reply_next_dead_base=link.REPLY_NEXT_DEAD_BASE if ctrl.model in NN_MODELS else None,
        ),
        announcement=announce.DESCRIPTION,
        modules=[_module(ctrl, res) for res in results],
        links=wires,
        flash_order=order,
    )
