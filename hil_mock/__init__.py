"""hil_mock: a virtual BS2sx per module (programming-protocol device side, token interpreter,
pyserial ``bstwin://`` URL handler and pty endpoint) and the robot twin built from them.
"""

from __future__ import annotations

from hil_mock.urlhandler import register as _register_url_handler

_register_url_handler()
