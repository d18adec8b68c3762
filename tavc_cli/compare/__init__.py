"""`tavc compare`: learners side by side on the chapter's five task-allocation scenarios.

Every controller named (built-in, from the literature, or the user's own through ``--config-dir``)
runs every scenario (`scenarios`) at one scale through the ordinary pipeline, each into a run
folder of its own (``RESULTS/runs/<controller>/<experiment>``, every table and claim as ``tavc
run`` writes them); `metrics` reads four numbers per trial from those folders and tests each
controller against TAVC and against random allocation; `figures` draws them and `write`
writes the table, the per-trial numbers and a short reading of them.

The controllers that learn nothing (random, the static allocations, the model's) have the same
distribution at every horizon: at a scale that runs baselines on the chapter's schedule
(``scale.baseline_time_factor``, scale=converged) they run that schedule, as the baselines of every
run do, and the table says at which multiple of the chapter's durations each row ran.
"""

from tavc_cli.chapter import served_by

SCENARIOS = served_by("compare", own=True)  # the chapter's scenarios, in its order
CONTROLLERS = ("tavc", "random", "model", "informed", "wolf_phc", "threshold")
REFERENCE, FLOOR = "tavc", "random"  # every controller is tested against these two


def scenarios() -> tuple[str, ...]:
    """The scenarios `tavc compare` runs by default, in the report's order (`Experiment.order`):
    the chapter's, and any of the user's own whose registry entry says compare serves it
    (``compare=True``, from ``--config-dir``)."""
    return served_by("compare")
