"""The ``bstool`` command group.

Commands live in ``bstool/commands/<name>.py`` (one module each, attribute ``command``) and are
imported only when used, so ``bstool --help`` stays fast and a broken optional command cannot
break the others. Add a command by adding a line to ``COMMANDS``.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys

import click

from bstool.errors import BstoolError
from bstool.version import __version__

# name -> (module, one-line help shown by `bstool --help`)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": (
        "bstool.commands.demo",
        "Whole chain on the built-in controller: compile, flash 30 twins, run, compare.",
    ),
    "simulate": (
        "bstool.commands.simulate",
        "Run a controller (or a states file) on the MuJoCo robot.",
    ),
    "model": ("bstool.commands.model", "Write the generated MJCF robot model."),
    "robot": ("bstool.commands.robot", "Print the default robot file to edit, or check one."),
    "states": ("bstool.commands.states", "Print the reference state sequence of a controller."),
    "evolve": (
        "bstool.commands.evolve",
        "Evolve a controller with the paper's GA (or co-evolution).",
    ),
    "plot-history": (
        "bstool.commands.plot_history",
        "Plot max/mean fitness per generation of evolve runs.",
    ),
    "tokenize": (
        "bstool.commands.tokenize",
        "Tokenize a PBASIC 2.5 program into BS2sx EEPROM images.",
    ),
    "compile": (
        "bstool.commands.compile",
        "Compile a controller into PBASIC programs and images per module.",
    ),
    "flash": ("bstool.commands.flash", "Upload images to BS2sx modules over a serial port."),
    "probe": ("bstool.commands.probe", "Measure a stamp's timing; write a bstool.timing/1 file."),
    "twin": (
        "bstool.commands.twin",
        "Run a compiled robot on 30 virtual BS2sx modules driving MuJoCo.",
    ),
    "faults": ("bstool.commands.faults", "Degree of mobility under module failures (paper §5.1)."),
    "extrapolate": (
        "bstool.commands.extrapolate",
        "Distance beyond MAX_TRANS, with optional re-initialisation.",
    ),
    "paths": (
        "bstool.commands.paths",
        "Disc paths of several controllers on one figure (Fig. 18).",
    ),
    "rotate": ("bstool.commands.rotate", "Shift a controller's legs to turn its heading."),
    "sensitivity": (
        "bstool.commands.sensitivity",
        "How far gaits transfer to robots with other physics (the uncertain ranges).",
    ),
    "report": ("bstool.commands.report", "HTML report comparing evolve runs and controllers."),
    "campaign": (
        "bstool.commands.campaign",
        "Evolve every model and seed of a plan, analyse the runs, report the paper's claims.",
    ),
}


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [name for name, (module, _) in COMMANDS.items() if _module_exists(module)]

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module_name, _ = COMMANDS[name]
        if not _module_exists(module_name):
            return None
        module = importlib.import_module(module_name)
        command: click.Command = module.command
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, COMMANDS[name][1]) for name in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


def _module_exists(module_name: str) -> bool:
    return importlib.util.find_spec(module_name) is not None


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="bstool")
def cli() -> None:
    """bstool: evolve brittle-star robot controllers in MuJoCo and run them on BS2sx modules.

    Pipeline: evolve -> best.json -> compile -> tokenize -> flash (or twin).
    Run `bstool COMMAND --help` for each step.
    """


def main(argv: list[str] | None = None) -> int:
    """Console entry point: user errors print one clear message and exit non-zero."""
    try:
        # standalone_mode=False returns what a command's ctx.exit(n) asked for instead of
        # calling sys.exit: that number is the exit code (the twin's verdict, docs/cli.md)
        returned = cli.main(args=argv, prog_name="bstool", standalone_mode=False)
    except BstoolError as exc:
        click.secho(f"Error: {exc}", fg="red", err=True)
        if exc.hint:
            click.echo(f"Hint: {exc.hint}", err=True)
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("Aborted.", err=True)
        return 130
    except KeyboardInterrupt:
        click.echo("Interrupted.", err=True)
        return 130
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except click.exceptions.Exit as exc:
        return exc.exit_code
    return returned if isinstance(returned, int) and not isinstance(returned, bool) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
