"""The distinct failures of a flash session, all :class:`bstool.errors.DeviceError`.

Each carries a one-line message and a hint; library users can catch the precise type.
"""

from __future__ import annotations

from bstool.errors import DeviceError


class PortError(DeviceError):
    """The serial port cannot be opened: missing, busy, no permission, bad URL."""


class NoEchoError(DeviceError):
    """Nothing came back at all: no power, no cable, wrong port."""


class NoReplyError(DeviceError):
    """The line echoes but no stamp answers identification: not in programming mode."""


class WrongStampError(DeviceError):
    """A stamp answered, but it is not a BS2sx (or answered something unknown)."""


class RecordRefusedError(DeviceError):
    """The stamp acknowledged a record with an error code, again after the retries."""

    def __init__(self, message: str, *, code: int, record: int, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.code = code
        self.record = record


class EchoMismatchError(DeviceError):
    """The echo kept differing from what was sent (line noise)."""


class FlashTimeoutError(DeviceError):
    """The stamp stopped answering in the middle of a session."""


class AnnouncementError(DeviceError):
    """The program that started after the upload names another module or controller."""


class FlashInterrupted(DeviceError):
    """Ctrl-C during an upload; says which module/slot may be incomplete."""

    exit_code = 130
