"""The arguments several commands of ``tavc`` share (their Hydra overrides, the progress flag)
and how every command's help lists them: without type labels."""

from functools import partial
from pathlib import Path
from typing import Annotated, Any, Optional

import typer
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

from tavc_cli.io import folder_problem


def overrides_of(example: str) -> Any:
    """The type of a command's Hydra overrides, its help showing `example`."""
    return Annotated[Optional[list[str]], typer.Argument(help=f"Hydra overrides, e.g. {example}.", show_default=False)]


Overrides = overrides_of("experiment=initial_distribution scale=paper team.n_robots=5")


CalibratedFrom = Annotated[Optional[Path], typer.Option(
    "--calibrated", show_default=False,
    help="A results folder holding the calibration searches (make calibrate-readings): measure each reading at the "
         "settings its own search chose against the chapter's facts, not at its defaults.")]

ProgressFlag = Annotated[
    Optional[bool],
    typer.Option(
        "--progress/--no-progress",
        help="Show progress while simulating: a bar on a terminal, a line every 10 s otherwise (the default); "
             "--no-progress prints results only.",
        show_default=False,
        metavar="",  # a flag takes no value: no type label beside it
    ),
]


def folder(text: str, *, in_setting: bool = False) -> Path:
    """A folder named on the command line (`--results`, the report's RESULTS_DIR): one line where
    it is empty or the root of the file system (`io.folder_problem`; `in_setting`, a folder the
    command names in its settings, also where it holds ``${``)."""
    problem = folder_problem(text, in_setting=in_setting)
    if problem is not None:
        raise typer.BadParameter(problem)
    return Path(text)


def results(help_text: str, show_default: bool = False) -> Any:
    """A command's ``--results`` option: the folder it writes, whose folders it names in its runs'
    settings, checked as `folder` checks such a folder."""
    return typer.Option("--results", help=help_text, show_default=show_default,
                        parser=partial(folder, in_setting=True))


def shown(progress: Optional[bool]) -> bool:
    """Whether to show progress: as asked, else yes (`pool.Progress` picks a bar or lines)."""
    return True if progress is None else progress


def _untyped(params: list) -> list:
    """The parameters as the help lists them, without type labels (`<bool>`, `<list[str]>`): each
    option's help says what it takes, and an argument is shown by its name."""
    for p in params:
        if isinstance(p, TyperOption) and p.metavar is None:
            p.metavar = ""
        elif isinstance(p, TyperArgument) and p.metavar is None:
            p.metavar = p.name.upper()
            p.display_type_rich = lambda ctx: None  # its name says what it is
    return params


class UntypedGroup(TyperGroup):
    """The app's group, its help without type labels (`_untyped`)."""

    def get_params(self, ctx) -> list:
        """The parameters, as the help lists them (`_untyped`)."""
        return _untyped(super().get_params(ctx))


class UntypedCommand(TyperCommand):
    """A command whose help has no type labels (`_untyped`)."""

    def get_params(self, ctx) -> list:
        """The parameters, as the help lists them (`_untyped`)."""
        return _untyped(super().get_params(ctx))


def untyped_help(app: typer.Typer) -> None:
    """Every command of `app` registered so far lists its help without type labels."""
    for info in app.registered_commands:
        info.cls = UntypedCommand if info.cls in (None, TyperCommand) else info.cls
