"""Pure-Python PBASIC 2.5 tokenizer for the BS2sx (byte-exact with Parallax's).

``tokenize_file(path)`` / ``tokenize_source(text, filename)`` return a :class:`Project` whose
``slots`` map slot numbers to :class:`SlotImage` (2048-byte EEPROM image, download records,
sizes). Errors are :class:`bstool.errors.SourceError` with file, line, column and Parallax's
error number. See docs/tokenizer.md.
"""

from bstool.tokenizer.project import Project, SlotImage, tokenize_file, tokenize_source

__all__ = ["Project", "SlotImage", "tokenize_file", "tokenize_source"]
