"""Overrides as Hydra's grammar reads them, one by one so that an error names the one at fault,
and sweeps (``a=1,2``, ``range(...)``, ``choice(...)``) expanded into the jobs they stand for."""

import itertools
import re
from collections.abc import Callable, Sequence
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, OverrideParseException

from tavc_cli.config.folders import config_folders, find_conf_dir
from tavc_cli.config.messages import override_syntax_message
from tavc_cli.errors import TavcError
from tavc_cli.override_keys import override_key, setting_key

# a sweep of more jobs is a slip (range(0,100000000)), not a study: each job is a run of its own
MAX_SWEEP_JOBS = 10_000


def is_hydra_override(text: str) -> bool:
    """Whether an override sets Hydra's own config (``hydra/launcher=...``, ``hydra.x=...``)."""
    key = text.lstrip("~+").split("=", 1)[0].strip()
    return key == "hydra" or key.startswith(("hydra.", "hydra/"))


def expand_sweep(overrides: Sequence[str]) -> list[list[str]]:
    """Expand Hydra sweep syntax into the override list of every job.

    Comma lists (``a=1,2``), ``range(...)`` and ``choice(...)`` are expanded into their cartesian
    product in the order given, as Hydra's basic sweeper does; a key given twice keeps its last
    value.

    Args:
        overrides: Overrides that may contain sweeps.

    Returns:
        One list of plain overrides per job.

    Raises:
        TavcError: On bad override syntax or a sweep that is not a discrete list of values.
    """
    choices = sweep_choices(overrides)
    return [list(job) for job in itertools.product(*choices.values())]


def swept_values(overrides: Sequence[str]) -> list[dict[str, str]]:
    """Each job's value of every swept key (as written), in sweep order.

    Raises:
        TavcError: On bad override syntax or a sweep that is not a discrete list of values.
    """
    choices = sweep_choices(overrides)
    swept = [key for key, values in choices.items() if len(values) > 1]
    return [{override_key(c): c.split("=", 1)[1] for c in job if override_key(c) in swept}
            for job in itertools.product(*choices.values())]


def parse_overrides(overrides: Sequence[str]) -> list:
    """Parse overrides one by one so that a syntax error names the override at fault (and says
    how to quote it, `messages.override_syntax_message`)."""
    parser = OverridesParser.create()
    parsed = []
    for index, text in enumerate(overrides):
        try:
            parsed.extend(parser.parse_overrides([text]))
        except OverrideParseException as error:
            raise TavcError(override_syntax_message(overrides, index, error, _parses(parser))) from None
        except RecursionError:  # the grammar's parser recurses once a level: [[[...]]] a few hundred deep
            raise TavcError(f"{override_key(text)}: its value is nested too deeply to read") from None
    return parsed


def _parses(parser: OverridesParser) -> Callable[[str], bool]:
    def parses(text: str) -> bool:
        try:
            parser.parse_overrides([text])
        except OverrideParseException:
            return False
        return True

    return parses


def sweep_choices(overrides: Sequence[str]) -> dict[str, list[str]]:
    """Map each override key to the plain overrides it expands to (one unless swept)."""
    choices: dict[str, list[str]] = {}
    for text, override in zip(overrides, parse_overrides(overrides), strict=True):
        key = override.get_key_element()
        if not override.is_sweep_override():
            choices[key] = [text]
        elif override.is_discrete_sweep():
            try:  # read lazily: range() with a huge stop is refused, not spelled out
                values = list(itertools.islice(override.sweep_string_iterator(), MAX_SWEEP_JOBS + 1))
            except HydraException:
                raise TavcError(
                    f"{key}: glob() sweeps are not supported; list the options"
                ) from None
            except ValueError as error:  # range() with a step of 0, say
                raise TavcError(f"{key}: {error}") from None
            if len(values) > MAX_SWEEP_JOBS:
                raise TavcError(f"{key}: the sweep gives it more than {MAX_SWEEP_JOBS:,} values; a sweep runs at most "
                                f"{MAX_SWEEP_JOBS:,} jobs")
            choices[key] = [f"{key}={value}" for value in values]
        else:
            raise TavcError(f"{key}: only lists, range() and choice() can be swept, not interval()")
    return choices


def refuse_deletions(overrides: Sequence[str]) -> None:
    """Refuse ``~key`` overrides: tavc reads every setting of its schema, so Hydra's deletion would
    not remove one but put the schema's default in its place, silently (``~seed`` would run seed 0).

    Raises:
        TavcError: Naming the first key given with ``~``; a config group's (``team``, ``learner``,
            ...) is told to choose an option.
    """
    for text in overrides:
        if text.lstrip().startswith("~"):
            key = setting_key(text)
            group = key.split("@", 1)[0]
            instead = (f"choose an option ({group}=<option>)" if (find_conf_dir() / group).is_dir()
                       else f"set it ({key}=<value>)")
            raise TavcError(f"{key}: every run reads it, so ~ cannot remove it (the schema's default would "
                            f"take its place); {instead}")


def refuse_group_lists(overrides: Sequence[str]) -> None:
    """Refuse a list given for a config group (``experiment=[value_change,breakdown]``): Hydra would
    merge the options' files into one config, named after the last and holding the others' events
    and settings, which the report would read as the last one's.

    Raises:
        TavcError: Naming the first group given a list.
    """
    for text in overrides:
        if is_hydra_override(text) or text.lstrip().startswith("~"):
            continue
        group = setting_key(text).split("@", 1)[0]
        if not group or not any((folder / group).is_dir() for folder in config_folders()):
            continue
        for override in parse_overrides([text]):
            if not override.is_sweep_override() and isinstance(override.value(), list):
                raise TavcError(f"{group}: takes one option, not a list (Hydra would merge the options into one "
                                f"config named after the last); choose one ({group}=<option>), or sweep them with -m "
                                f"({group}=a,b)")


def slug(choices: Any) -> str:
    """A short, filesystem-safe folder name from ``key=value`` overrides."""
    text = ",".join(choices)
    return re.sub(r"[^A-Za-z0-9._=,+-]", "_", text)[:80]
