"""Pure-Python PBASIC 2.5 tokenizer for the BS2sx (byte-exact with Parallax's)."""
