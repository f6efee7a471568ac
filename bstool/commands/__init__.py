"""One module per `bstool` subcommand; each defines ``command``."""
