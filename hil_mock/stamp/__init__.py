"""A virtual BS2sx: token interpreter, memory and virtual clock (see docs/twin.md)."""

from .errors import NotInTwin, StampFault
from .interpreter import NEVER, RecordingIO, SerialWait, Stamp, StampIO, Status
from .memory import Memory, SimpleEeprom, SlotStore

__all__ = [
    "NEVER",
    "Memory",
    "NotInTwin",
    "RecordingIO",
    "SerialWait",
    "SimpleEeprom",
    "SlotStore",
    "Stamp",
    "StampFault",
    "StampIO",
    "Status",
]
