"""WIRING.md: everything a person with 30 modules on the bench needs to build, calibrate, flash
and start the robot compiled into this build (rendered from bstool/data/wiring.md.j2)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jinja2

from bstool.compile.topology import PORTS, SERVO_PIN, pin_role
from bstool.controllers import NN_MODELS
from bstool.moduleid import ModuleId
from bstool.robot import RobotSpec
from bstool.wire import announce

if TYPE_CHECKING:
    from bstool.buildfile import Manifest
    from bstool.compile.results import ModuleResult
    from bstool.controllers import Controller


def _port_text(model: str) -> dict[str, str]:
    """What each link port joins, said for this model (NN legs are chains, CA legs rings)."""
    ring = model not in NN_MODELS
    return {
        "prev": "previous module along the leg (towards the disc)"
        + ("; the lead's P0 goes to the tip of its own leg (the leg is a ring)" if ring else ""),
        "next": "next module along the leg (towards the tip)"
        + ("; the tip's P1 goes to the lead of its own leg" if ring else ""),
        "lead_left": "the lead of leg i-1 (leads only)",
        "lead_right": "the lead of leg i+1 (leads only)",
        "bypass_prev": "the module two before along the leg (bypass around a dead j-1)",
        "bypass_next": "the module two after along the leg (bypass around a dead j+1)",
    }


def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.PackageLoader("bstool", "data"),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        autoescape=False,
    )


def wiring(
    ctrl: Controller, full_hash: str, results: list[ModuleResult], manifest: Manifest
) -> str:
    """The text of WIRING.md for a build of ``ctrl`` holding the modules of ``results``; the
    wires and the flashing order are the manifest's."""
    spec = RobotSpec(legs=ctrl.legs, modules=ctrl.modules, states=ctrl.k)
    roles = {
        pin_role(ctrl.model, ctrl.legs, ctrl.modules, r.plan.mid, ll.peer)
        for r in results
        for ll in r.plan.links
    }
    text = _port_text(ctrl.model)
    ports = [(PORTS[k], text[k]) for k in text if k in roles]
    first = manifest.flash_order[0].module if manifest.flash_order else ModuleId(0, 0)
    context = {
        "hash8": full_hash[:8],
        "announcement": announce.generic(full_hash[:8]),
        "model": ctrl.model,
        "nn": ctrl.model in NN_MODELS,
        "legs": ctrl.legs,
        "modules": ctrl.modules,
        "last_leg": ctrl.legs - 1,
        "last_module": ctrl.modules - 1,
        "angle_step": 360 // ctrl.legs if 360 % ctrl.legs == 0 else round(360 / ctrl.legs, 1),
        "axes": [(j, spec.axis_of(j)) for j in range(ctrl.modules)],
        "servo_pin": SERVO_PIN,
        "baud_debug": announce.BAUDMODE,
        "ports": ports,
        "bypass": "bypass_next" in roles,
        "wires": manifest.links,
        "window_s": manifest.link.power_up_window_ms / 1000,
        "order": manifest.flash_order,
        "first": str(first),
        "first_label": first.label,
    }
    return _environment().get_template("wiring.md.j2").render(**context)
