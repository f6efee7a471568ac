"""Faults a virtual BS2sx reports: all are :class:`bstool.errors.DeviceError`."""

from __future__ import annotations

from bstool.errors import DeviceError


class StampFault(DeviceError):
    """The program did something the real stamp cannot do sensibly (bad image, RETURN
    without GOSUB, a token stream that does not decode)."""


class NotInTwin(DeviceError):
    """An instruction the twin does not model; the message names it."""

    def __init__(self, what: str, *, where: str = "") -> None:
        at = f" (at {where})" if where else ""
        super().__init__(
            f"not implemented in the twin: {what}{at}",
            hint="use only the instructions listed in docs/twin.md, or run the program on a "
            "real BS2sx",
        )
        self.what = what
