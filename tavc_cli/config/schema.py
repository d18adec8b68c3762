"""The schemas, defined in `tavc_cli.settings` (the library reads them without Hydra)."""

from tavc_cli.settings import (
    ANALYSIS_STATES,
    AVAILABLE_BACKENDS,
    BACKENDS,
    MIN_DOCK_CLEARANCE_M,
    SCHEMA_NAME,
    TARGET_KINDS,
    TIME_UNITS,
    WALL_TOLERANCE_M,
    MemberConfig,
    TavcConfig,
)

__all__ = ["ANALYSIS_STATES", "AVAILABLE_BACKENDS", "BACKENDS", "MIN_DOCK_CLEARANCE_M", "SCHEMA_NAME", "TARGET_KINDS",
           "TIME_UNITS", "WALL_TOLERANCE_M", "MemberConfig", "TavcConfig"]
