"""The twin's link wires: which pins the build joins, and the bytes (and noise) on them.

A BS2sx has no receive buffer: a byte reaches exactly the neighbours that were listening
(SERIN) when its start bit began (the scheduler of :mod:`hil_mock.schedule` guarantees that).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from bstool.buildfile import Build
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from hil_mock.stamp import NEVER, Stamp

Wires = dict[tuple[ModuleId, int], list[tuple[ModuleId, int]]]
# A WELCOME's header, $D8 + t. On a CA link no other byte is $D8..$DF: a payload byte is
# (15 - x) ^ t << 4 + x (t = 0 without XOR, t <= 7), and a low nibble x >= 8 leaves a high
# nibble <= 7. (NN packs other payloads: there the tap is not used.)
WELCOME = 0xD8


def check_cuts(build: Build, cut: Iterable[tuple[ModuleId, ModuleId]]) -> None:
    """Refuse a cut of two modules no wire joins."""
    wired = {frozenset((w.master, w.slave)) for w in build.manifest.links}
    for a, b in cut:
        if frozenset((a, b)) not in wired:
            raise InputError(
                f"cannot cut {a}-{b}: no wire joins these modules in this build",
                hint="WIRING.md lists the wires",
            )


def wires(build: Build, cut: Iterable[tuple[ModuleId, ModuleId]]) -> Wires:
    """(module, pin) -> the (module, pin) ends it is wired to, without the ``cut`` wires
    (checked with :func:`check_cuts` by the caller)."""
    ends = [(w.master, w.master_pin, w.slave, w.slave_pin) for w in build.manifest.links]
    cuts = {frozenset(c) for c in cut}
    out: Wires = {}
    for a, pin_a, b, pin_b in ends:
        if frozenset((a, b)) not in cuts:
            out.setdefault((a, pin_a), []).append((b, pin_b))
            out.setdefault((b, pin_b), []).append((a, pin_a))
    return out


class Links:
    """Link routing with noise, a mixin of :class:`hil_mock.robot.RobotTwin`. ``noise`` is the
    chance that a byte on a link is hit (half of the hits drop it, half flip one bit)."""

    noise: float
    # one noise stream per sender, so what hits a module's k-th byte does not depend on the
    # order in which the scheduler runs the modules
    noise_rngs: dict[ModuleId, np.random.Generator]
    noise_events: dict[str, int]
    wires: Wires
    stamps: dict[ModuleId, Stamp]
    # (sender, receiver, start ns) of every WELCOME header sent, hit by noise or not: a CA
    # sender counts its neighbour alive again once it sent it (hil_mock.outage)
    welcomes: list[tuple[ModuleId, ModuleId, int]]
    # wires cut during the run: {the two modules: the virtual ns from which no byte crosses}
    cut_at_ns: dict[frozenset[ModuleId], int]
    # one-way wires: {(sender, receiver): the virtual ns from which its bytes to it are lost}
    lost_ns: dict[tuple[ModuleId, ModuleId], int]

    def _route(self, mid: ModuleId, pin: int, value: int, start_ns: int, mode: int) -> None:
        if value & 0xF8 == WELCOME:
            ends = self.wires.get((mid, pin), ())
            self.welcomes.extend((mid, peer, start_ns) for peer, _ in ends)
        if self.noise and (rng := self.noise_rngs[mid]).random() < self.noise:
            if rng.random() < 0.5:  # the byte is lost (a start bit not seen)
                self.noise_events["dropped"] += 1
                return
            value ^= 1 << int(rng.integers(8))  # one bit flipped on the wire
            self.noise_events["flipped"] += 1
        tx_bit_ns = self.stamps[mid].clock.bit_ns(mode)  # the sender's own bit time
        cut_at, lost = self.cut_at_ns, self.lost_ns
        for peer, peer_pin in self.wires.get((mid, pin), ()):
            if cut_at and start_ns >= cut_at.get(frozenset((mid, peer)), NEVER):
                continue  # the wire came loose
            if lost and start_ns >= lost.get((mid, peer), NEVER):
                continue  # the peer's receive line is broken: the wire works one way only
            stamp = self.stamps.get(peer)
            if stamp is not None:
                stamp.deliver_byte(peer_pin, value, start_ns, mode, tx_bit_ns)
