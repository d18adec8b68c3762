"""What an animation pictures: `tavc animate` records the settings it simulated beside each
animation it writes (`<name>.settings.yaml` beside `<name>.gif`), so that a run taking a folder
that holds animations and no run of its own compares its settings with theirs, and an animation
of other settings is never left beside a run, taken for that run's."""

from __future__ import annotations

from pathlib import Path

from tavc_cli.io import owned_path
from tavc_cli.ownership import Owned, config_differences

SETTINGS_SUFFIX = ".settings.yaml"


def settings_record(gif: Path) -> Path:
    """Where the settings of the animation `gif` are recorded: `<name>.settings.yaml` beside it."""
    return gif.with_name(gif.stem + SETTINGS_SUFFIX)


def animation_differences(owned: Owned, new_yaml: str) -> tuple[str | None, list[str]]:
    """How the animations tavc wrote in `owned`'s folder (each GIF its record lists, named in any
    case) picture other settings than `new_yaml`, the first such by name: why its settings are
    unknown (its record missing: a `tavc animate` stopped before writing it), or how they differ
    (`ownership.config_differences`). (None, []) where each pictures these settings. A record is
    read only inside the folder: a link there is refused in one line (`io.owned_path`)."""
    for gif in sorted(n for n in owned.files if Path(n).suffix.lower() == ".gif"):
        if not (owned.folder / gif).is_file():
            continue
        record = owned_path(owned.folder, settings_record(owned.folder / gif), what="output_dir")
        if not record.is_file():
            return f"{record.name} is missing", []
        differ = config_differences(record, new_yaml)
        if differ:
            return None, differ
    return None, []
