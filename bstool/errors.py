"""The few exception types bstool raises for problems a user can fix.

Every stage raises a subclass of :class:`BstoolError`; the CLI prints its message (and hint)
on one or two lines and exits non-zero, never with a traceback. Library users catch them.
"""

from __future__ import annotations


class BstoolError(Exception):
    """A problem the user can act on. ``hint`` says what to do about it."""

    exit_code = 1

    def __init__(self, message: str, *, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint

    def __str__(self) -> str:
        return self.message


class InputError(BstoolError):
    """A file or argument is missing, malformed or inconsistent (JSON, controller, states...)."""

    exit_code = 2


class SourceError(BstoolError):
    """A PBASIC source cannot be tokenized; carries the position like a compiler does."""

    exit_code = 3

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        code: int | None = None,
        hint: str | None = None,
    ) -> None:
        super().__init__(message, hint=hint)
        self.file = file
        self.line = line
        self.column = column
        self.code = code

    def __str__(self) -> str:
        where = ":".join(str(p) for p in (self.file, self.line, self.column) if p is not None)
        number = f" [{self.code}]" if self.code is not None else ""
        return f"{where}: error{number}: {self.message}" if where else self.message


class DeviceError(BstoolError):
    """A serial port, a stamp or a twin did not behave (missing port, no echo, NAK, timeout)."""

    exit_code = 4


class BuildError(BstoolError):
    """A controller cannot be compiled for the robot (does not fit, bad calibration...)."""

    exit_code = 5
