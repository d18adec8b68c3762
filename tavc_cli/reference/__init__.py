"""The chapter's numbers, as data shipped with the package."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

_HERE = Path(__file__).resolve().parent


@cache
def chapter_world() -> dict:
    """Facts the chapter states about its simulated world (speed, values, arrivals per trial)."""
    return json.loads((_HERE / "world.json").read_text())


def chapter_table(table_id: str):
    """Table `table_id` ("1.1" ... "1.6") as the chapter printed it, a pandas DataFrame."""
    # deferred: loads pandas
    import pandas as pd

    return pd.read_csv(_HERE / f"table_{table_id.replace('.', '_')}.csv", dtype={"state": str})
