"""bstool: from evolved brittle-star controllers to code running on BS2sx modules."""

__version__ = "0.1.0"
