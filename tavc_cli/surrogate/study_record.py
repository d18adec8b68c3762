"""What a surrogate study's tables were made with: ``study.json`` in its folder records the
settings all of the study's runs share, as composed for its base case (where and how fast they
run apart), and the folder of the simulator's runs they are compared with.

The study is often run a part at a time (``--parts``), each part adding its table beside the
others, and the report reads them as one study; a part of other settings would sit beside them
unnoticed, and the figures drawn from all the tables would mix them. So a part whose settings
differ from the record is refused in one line naming the difference, unless ``overwrite=true``,
which removes the earlier parts' tables and figures first. A folder without a record is
taken as it is, and recorded from then on.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

import yaml

from tavc_cli.errors import TavcError
from tavc_cli.io import write_text_atomic
from tavc_cli.ownership import NOT_RESULTS, Owned, recorded_differences
from tavc_cli.settings import TavcConfig, to_yaml

RECORD = "study.json"


def identity(settings: TavcConfig, simulator: Path) -> dict:
    """The record of a study whose runs share `settings` (its base case's, as composed with the
    study's overrides), compared with the simulator's runs in `simulator`."""
    composed = yaml.safe_load(to_yaml(settings))
    return {"settings": {k: v for k, v in composed.items() if k not in NOT_RESULTS},
            "simulator": str(Path(simulator).resolve())}


def keep_record(owned: Owned, out: Path, made_with: dict, overwrite: bool, files: Iterable[str]) -> None:
    """Check the study folder `out` (what tavc owns there: `owned`) against `made_with` (`identity`)
    as the module's docstring says, remove the earlier parts' `files` where they were made otherwise
    and `overwrite` allows it, and record `made_with`."""
    differ = recorded_differences(out / RECORD, made_with) if owned.owns(RECORD) else []
    if differ and not overwrite:
        raise TavcError(f"--results: {out} holds a study made with other settings ({'; '.join(differ)}); add "
                        "overwrite=true to replace its tables, or choose another folder")
    for name in sorted(files) if differ else ():
        owned.remove(name)
    owned.wrote(RECORD)
    write_text_atomic(out / RECORD, json.dumps(made_with, indent=1) + "\n")
