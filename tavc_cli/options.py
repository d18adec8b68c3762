"""The arguments several commands of ``tavc`` share: their Hydra overrides and the progress flag."""

from typing import Annotated, Any, Optional

import typer


def overrides_of(example: str) -> Any:
    """The type of a command's Hydra overrides, its help showing `example`."""
    return Annotated[Optional[list[str]], typer.Argument(help=f"Hydra overrides, e.g. {example}.", show_default=False)]


Overrides = overrides_of("experiment=initial_distribution scale=paper team.n_robots=5")


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


def shown(progress: Optional[bool]) -> bool:
    """Whether to show progress: as asked, else yes (`pool.Progress` picks a bar or lines)."""
    return True if progress is None else progress
