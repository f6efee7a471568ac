"""``bstool compile``: a controller file → PBASIC programs per module, images, manifest, wiring.

See docs/compile.md for the design and protocol/link.md for the module-to-module link.
"""

from bstool.compile.build import BuildResult, compile_controller
from bstool.compile.render import templates_dir

__all__ = ["BuildResult", "compile_controller", "templates_dir"]
