"""The build's descriptions: its manifest (bstool.buildfile, bstool.build/1) and WIRING.md."""

from __future__ import annotations

import hashlib
from typing import Any

from bstool import buildfile as bf
from bstool.compile.plan import ModulePlan
from bstool.compile.results import ModuleResult, SlotResult
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
    pins = [bf.Pin(SERVO_PIN, "servo")]
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
                bypass=ll.link.bypass,
                send_states=len(ll.send),
                receive_states=len(ll.store),
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
        dead_ticks=p.dead_ticks,
        timing=bf.Timing(**res.timing),
        ram_map=res.ram_map or None,
    )


def _link_settings(nn: bool, hold_frames: int, plan: ModulePlan | None = None) -> bf.LinkSettings:
    k = link.serve_constants(nn)
    return bf.LinkSettings(
        protocol="protocol/link.md",
        baud=link.BAUD,
        baudmode=link.BAUDMODE,
        pace_ms=k.pace_ms,
        hold_frames=hold_frames,  # from the period (plan.hold_for_period)
        listen_units=k.listen,
        reply_wait_units=k.reply_wait,
        payload_wait_units=k.payload_wait,
        jitter_units=k.jitter_units,
        keepalive_rounds=k.keepalive_rounds,
        dead_limit_ms=k.dead_limit_ms,
        power_up_window_ms=k.power_up_window_ms,
        states_wait_units=k.states_wait,
        pace_ticks=k.pace_ticks,
        **_quiet(nn),
        **_hold_clock(plan),
    )


def _hold_clock(plan: ModulePlan | None) -> dict[str, int | None]:
    """CA: the hold clock's estimates (the same in every module's plan) and the tries in a row."""
    if plan is None or plan.family != "ca":
        return {}
    return {
        "frame_units": plan.frame_units,
        "master_try_units": plan.master_try_units,
        "listen_try_units": plan.listen_try_units,
        "heard_try_units": plan.heard_try_units,
        "ask_tries": plan.serve.ask_tries,
        "lack_tries": plan.serve.lack_tries,
    }


CA_QUIET_FIELDS = ("tick", "ask", "listen", "heard", "ask_heard")
"""The silence clock's fields (bstool.wire.link.CaQuiet), each ``link.<field>_quiet_units``."""


def _quiet(nn: bool) -> dict[str, int | None]:
    """CA: the silence clock's constants (bstool.wire.link.ca_quiet); NN: none."""
    if nn:
        return {}
    q = link.ca_quiet()
    return {f"{name}_quiet_units": getattr(q, name) for name in CA_QUIET_FIELDS}


def manifest(
    ctrl: Controller,
    source: str,
    full_hash: str,
    period: float,
    results: list[ModuleResult],
    tokenized: bool,
    robot_values: dict[str, Any] | None = None,
) -> bf.Manifest:
    """The build's manifest (bstool.build/1) for ``results``; ``robot_values``: the robot it
    is compiled for when not the default (``Robot.to_json``)."""
    wires = [
        bf.Wire(lk.master, lk.master_pin, lk.slave, lk.slave_pin, lk.colour, lk.bypass)
        for lk in links(ctrl.model, ctrl.legs, ctrl.modules)
    ]
    hold = (
        results[0].plan.hold_frames
        if results
        else link.serve_constants(ctrl.model in NN_MODELS).hold_frames
    )
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
        link=_link_settings(ctrl.model in NN_MODELS, hold, results[0].plan if results else None),
        announcement=announce.DESCRIPTION,
        modules=[_module(ctrl, res) for res in results],
        links=wires,
        flash_order=order,
        robot_values=robot_values,
    )
