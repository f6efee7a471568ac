"""What is being evolved: a model's populations, their chromosomes, and their state sequences.

ca1d, ca2dsing, nnsig and nnsin have one population ("main"). ca2ddiff co-evolves two
(§3.4): "control" (lead initial states + control rule) and "leg" (non-lead initial states +
leg rule); a candidate of one is always run together with a partner from the other.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bstool.controllers import Controller, make_controller
from bstool.controllers import chromosome as ch
from bstool.controllers.reference import CA_MODELS, MODELS, NN_MODELS
from bstool.controllers.sequences import ca_sequences, nn_sequences

Bits = npt.NDArray[np.uint8]
Sequences = npt.NDArray[np.uint8]


@dataclass(frozen=True)
class Problem:
    model: str
    legs: int = 5
    modules: int = 6
    transitions: int = 30  # MAX_TRANS

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"unknown model {self.model!r}")

    @property
    def populations(self) -> tuple[str, ...]:
        return ("leg", "control") if self.model == "ca2ddiff" else ("main",)

    def partner_of(self, name: str) -> str | None:
        return {"leg": "control", "control": "leg"}.get(name)

    def length(self, name: str) -> int:
        n, m = self.legs, self.modules
        if name == "control":
            return ch.control_length(n)
        if name == "leg":
            return ch.leg_length(n, m)
        return ch.nn_length(n, m) if self.model in NN_MODELS else ch.ca_length(n, m)

    def _ca2ddiff(self, control: Bits, leg: Bits) -> tuple[npt.NDArray[np.uint8], Bits]:
        leads, cr = ch.decode_control(control, self.legs)
        others, lr = ch.decode_leg(leg, self.legs, self.modules)
        p = max(len(leads), len(others))
        initial = np.empty((p, self.legs, self.modules), dtype=np.uint8)
        initial[:, :, 0] = leads
        initial[:, :, 1:] = others
        rules = np.stack(np.broadcast_arrays(cr, lr), axis=1)
        return initial, rules

    def sequences(
        self,
        name: str,
        bits: Bits,
        partner: Bits | None = None,
        failed: Iterable[tuple[int, int]] = (),
    ) -> Sequences:
        """State sequences (P, T+1, n, m) of the population ``bits`` (P, L); ``failed``
        (leg, module) cells keep their R^0 state."""
        T = self.transitions
        if self.model in NN_MODELS:
            leads, weights = ch.decode_nn(bits, self.legs, self.modules)
            return nn_sequences(self.model, leads, weights, T, failed)
        if self.model == "ca2ddiff":
            assert partner is not None
            pair = (bits, partner[None]) if name == "control" else (partner[None], bits)
            initial, rules = self._ca2ddiff(*pair)
            return ca_sequences(self.model, initial, rules, T, failed)
        initial, rule = ch.decode_ca(bits, self.legs, self.modules)
        return ca_sequences(self.model, initial, rule, T, failed)

    def chromosomes(self, controller: Controller) -> dict[str, Bits]:
        """The chromosome of each population that decodes to ``controller`` (the inverse of
        :meth:`controller`): ``evolve --init`` starts from it."""
        if (controller.model, controller.legs, controller.modules) != (
            self.model, self.legs, self.modules
        ):  # fmt: skip
            raise ValueError(f"a {controller.model} controller for a {self.model} problem")
        init = controller.initial_states[None]
        if self.model in NN_MODELS:
            assert controller.weights is not None
            return {"main": ch.encode_nn(init[:, :, 0], controller.weights[None])[0]}
        if self.model == "ca2ddiff":
            assert controller.control_rule is not None and controller.leg_rule is not None
            return {
                "control": ch.encode_control(init[:, :, 0], controller.control_rule[None])[0],
                "leg": ch.encode_leg(init[:, :, 1:], controller.leg_rule[None])[0],
            }
        assert controller.rule is not None
        return {"main": ch.encode_ca(init, controller.rule[None])[0]}

    def controller(
        self, name: str, row: Bits, partner: Bits | None = None, **meta: Any
    ) -> Controller:
        """The decoded controller of one chromosome (with its partner for ca2ddiff)."""
        one = row[None]
        if self.model in NN_MODELS:
            leads, weights = ch.decode_nn(one, self.legs, self.modules)
            return make_controller(self.model, leads[0], weights=weights[0], **meta)
        if self.model == "ca2ddiff":
            assert partner is not None
            pair = (one, partner[None]) if name == "control" else (partner[None], one)
            initial, rules = self._ca2ddiff(*pair)
            return make_controller(
                self.model, initial[0], control_rule=rules[0, 0], leg_rule=rules[0, 1], **meta
            )
        assert self.model in CA_MODELS
        initial, rule = ch.decode_ca(one, self.legs, self.modules)
        return make_controller(self.model, initial[0], rule=rule[0], **meta)
