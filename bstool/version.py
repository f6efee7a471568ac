"""bstool's version, at the bottom of the layers so that any module may record it (controller
files, checkpoints, timing files, reports) without importing the package root."""

__version__ = "0.1.0"
