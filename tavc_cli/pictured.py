"""What an animation pictures: `tavc animate` records the settings it simulated beside each
animation it writes (`<name>.settings.yaml` beside `<name>.gif`), so that a run taking a folder
that holds animations and no run of its own compares its settings with theirs, and an animation
of other settings is never left beside a run, taken for that run's."""

from __future__ import annotations

from pathlib import Path

from tavc_cli.ownership import Owned, config_differences

SETTINGS_SUFFIX = ".settings.yaml"


def settings_record(gif: Path) -> Path:
    """Where the settings of the animation `gif` are recorded: `<name>.settings.yaml` beside it."""
    return gif.with_name(gif.stem + SETTINGS_SUFFIX)


def animation_differences(owned: Owned, new_yaml: str) -> list[str]:
    """How an animation tavc wrote in `owned`'s folder pictures other settings than `new_yaml`
    (`ownership.config_differences` of its record, the first such animation's by name); empty
    where each animation with a record pictures these settings. An animation without one is not
    compared."""
    for name in sorted(owned.files):
        gif = name.removesuffix(SETTINGS_SUFFIX) + ".gif"
        if name.endswith(SETTINGS_SUFFIX) and gif in owned.files and (owned.folder / name).is_file():
            differ = config_differences(owned.folder / name, new_yaml)
            if differ:
                return differ
    return []
