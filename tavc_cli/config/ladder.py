"""The horizon ladder's configs: the chapter's base case (initial_distribution) at several
multiples of the chapter's durations, one results folder a rung."""

import math
from collections.abc import Sequence
from pathlib import Path

from omegaconf import DictConfig

from tavc_cli.chapter import base_case
from tavc_cli.config.loading import load_config, results_root
from tavc_cli.errors import TavcError
from tavc_cli.io import owned_path, refuse_folder_problem
from tavc_cli.override_keys import setting, setting_key

LADDER_EXPERIMENT = base_case().name


def parse_factors(text: str | None) -> list[float] | None:
    """The ladder's comma-separated factors (``1,4,10,20,40``) as numbers; None when not given."""
    if text is None:
        return None
    try:
        return [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise TavcError(f"ladder factors: {text!r} is not a comma-separated list of numbers, "
                        "e.g. 1,4,10,20,40") from None


def ladder_folder(results_dir: str | Path, factor: float) -> Path:
    """Where a rung of the horizon ladder goes: ``<results_dir>/ladder/x<factor>``."""
    return Path(results_dir) / "ladder" / f"x{factor:g}"


def runs_beside(results_dir: str | Path, factors: Sequence[float]) -> list[Path]:
    """The run folders in ``<results_dir>/ladder/`` that are no rung of the ladder at `factors`
    (an earlier ladder's at a factor these leave out, a copy of one's own): kept, never removed,
    and named by the report as left out. Hidden folders and links are passed over, as the report
    passes them."""
    ladder = Path(results_dir) / "ladder"
    rungs = {ladder_folder(results_dir, f) for f in factors}
    return sorted((d for d in ladder.iterdir() if d.is_dir() and not d.is_symlink() and not d.name.startswith(".")
                   and (d / "config.yaml").is_file() and d not in rungs), key=lambda d: d.name) \
        if ladder.is_dir() else []


def load_ladder(factors: Sequence[float], overrides: Sequence[str] = (),
                results_dir: str | Path | None = None) -> list[DictConfig]:
    """The horizon ladder: initial_distribution at each factor of the chapter's durations
    (``scale.time_factor``; the rest of ``scale=converged``: its trial counts, the baselines on
    the chapter's schedule), one folder a rung (`ladder_folder`).

    Args:
        factors: Multiples of the chapter's durations, each > 0 and none twice.
        overrides: Hydra overrides for every rung; ``experiment``, ``output_dir`` and
            ``scale.time_factor`` are the ladder's and refused here.
        results_dir: The folder whose ``ladder/`` gets the rungs; by default ``runs/<scale>``
            (``runs/converged`` unless a scale is given).

    Raises:
        TavcError: For a bad factor, a refused key, or any override that fails.
    """
    factors = [float(f) for f in factors]
    if not factors or any(not math.isfinite(f) or f <= 0 for f in factors):
        raise TavcError("ladder factors: each must be a number above 0, e.g. 1,4,10,20,40")
    if len(set(factors)) != len(factors):
        raise TavcError("ladder factors: a factor is given twice")
    for override in overrides:
        key = setting_key(override)
        if key in ("experiment", "output_dir", "scale.time_factor"):
            raise TavcError(f"{key}: set by the ladder for each rung; choose the factors and the results folder "
                            "instead (--ladder, --results)")
    scale = [o for o in overrides if setting_key(o) == "scale"] or ["scale=converged"]
    rest = [o for o in overrides if setting_key(o) != "scale"]
    if results_dir is None:
        results_dir = results_root(overrides, "converged")
    refuse_folder_problem(results_dir, "--results", in_setting=True)
    folders = [owned_path(Path(results_dir), ladder_folder(results_dir, f), folder=True, what="--results")
               for f in factors]
    return [load_config([f"experiment={LADDER_EXPERIMENT}", *scale, f"scale.time_factor={f!r}", *rest,
                         setting("output_dir", folder)]) for f, folder in zip(factors, folders, strict=True)]
