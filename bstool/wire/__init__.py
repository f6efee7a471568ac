"""The wire formats, one module each, imported by the host (compile, flash) and the twin alike.

- :mod:`bstool.wire.programming`: the BS2sx programming protocol (protocol/programming.md);
- :mod:`bstool.wire.link`: the module-to-module link frames and settings (protocol/link.md);
- :mod:`bstool.wire.announce`: the start-up announcement every module program sends.

Nothing here touches a port; the normative specs and test vectors live in ``protocol/``.
"""
