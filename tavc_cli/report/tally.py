"""The tally under the report's two tables of the turn-taking model's checks: over the runs whose
learners converged at 40x (`no_check_note`), how often each model names their regime and the
turn-taking model their modal state, how firmly the learners' trials name it, the model's hits
where they name it firmly, and how near a tie the modal state is in odd teams that take turns."""

from __future__ import annotations

import math
import statistics
from pathlib import Path

import pandas as pd

from tavc_cli.analysis.turn_taking import ALTERNATOR, FIRM, HORIZON, modal_support, state_shares
from tavc_cli.notation import STATE_PREFIX, join_counts, state_counts
from tavc_cli.report.files import model_alternators, read_or_refuse
from tavc_cli.settings_studies import ALTERNATORS

# a prediction whose folder ends so was made after the learners' runs beside it were read, by a way of the
# model built after them: the report sets it beside those runs and tallies it apart from every check
POST_HOC = "-post_hoc"
EXPLORED = "-explorers"  # a prediction whose lone switchers were measured from explorers, beside the same name


def base_name(prediction: str) -> str:
    """The name of the scenario a prediction's folder is for: without the suffixes that name a way
    of the model (`EXPLORED`) or a prediction made after its runs were read (`POST_HOC`)."""
    return prediction.removesuffix(POST_HOC).removesuffix(EXPLORED)


def turn_tally(regime: str, state: str, support: float, learners: dict, alternators: dict | None = None) -> dict:
    """What `tally_line` counts of one prediction of the turn-taking model (its regime, its modal
    state and that state's `support`) beside the learners: whether each is theirs, the support, and
    their own modal state's (what a prediction could at best be confirmed by); and for
    `middle_line`, where the learners take turns in a team of odd size and their modal state is
    one of its two middle states (`middle_states`), their shares of both and the static
    alternators' (`alternator_shares`; None without their table)."""
    middle = middle_states(learners["modal_state"]) if learners["regime"] == "turn-taking" else None
    shares = _shares_of(learners["shares"], middle) if middle and learners["modal_state"] in middle else None
    return {"regime": regime == learners["regime"], "modal": state == learners["modal_state"], "support": support,
            "ceiling": support_of(learners, learners["modal_state"]),
            **({"middle": shares, "alternators": _shares_of(alternators or {}, middle)} if shares else {})}


def middle_states(state: str) -> tuple[str, str] | None:
    """The two middle states of the team of a state "h:l" (h robots on the high-value circuit, l on
    the low) where h + l is odd: (n+1)/2 high and (n-1)/2 high; None for an even team or a state
    of another form."""
    counts = state_counts(state)
    n = sum(counts) if counts is not None and len(counts) == 2 else 0
    return (join_counts((n // 2 + 1, n // 2)), join_counts((n // 2, n // 2 + 1))) if n % 2 else None


def _shares_of(shares: dict, states: tuple[str, str]) -> tuple[float, float] | None:
    return (float(shares[states[0]]), float(shares[states[1]])) if all(s in shares for s in states) else None


def alternator_shares(where: Path, predicted: dict) -> dict | None:
    """The static alternators' share (%) of the stable period in each state, from the run a
    prediction takes its modal state from (`files.model_alternators`); None where it has none. A
    table without its columns is refused in one line naming it."""
    run = model_alternators(where, predicted)
    if run is None or not (run / "state_time.csv").is_file():
        return None

    return read_or_refuse(run / "state_time.csv",
                          lambda path: state_shares(pd.read_csv(path, dtype={"state": str}), ALTERNATOR))


def _span(values: list[float]) -> str:
    low, high = f"{min(values):.1f}", f"{max(values):.1f}"
    return low if low == high else f"{low} to {high}"


def middle_line(tallies: list[dict]) -> list[str]:
    """Over the rows whose learners converged, take turns in a team of odd size and are modal in
    one of its two middle states: how far apart their shares of the two are, how often the model
    named their modal state there (a near tie decides it), and how far apart the static
    alternators' shares of the same states are."""
    odd = [t for t in tallies if t["check"] and "middle" in t]
    if not odd:
        return []
    gaps = [abs(a - b) for a, b in (t["middle"] for t in odd)]
    lows = [min(t["middle"]) for t in odd]
    resampled = [t["support"] for t in odd if math.isfinite(t["support"])]
    which = "" if len(resampled) == len(odd) else " with a table of their trials"
    expected = f" (over resamples of their trials, in {sum(resampled):.1f} of the {len(resampled)}{which} on " \
               "average)" if resampled else ""
    alt = [abs(a - b) for a, b in (t["alternators"] for t in odd if t["alternators"])]
    some = "" if len(alt) == len(odd) else f"; at the {len(alt)} with their table"
    beside = (f"; the static alternators' shares of the same two states, which the model reads its modal state "
              f"from, differ by {_span(alt)} (median {statistics.median(alt):.1f}{some})" if alt else "")
    runs = f"{len(odd)} run" + ("s" if len(odd) != 1 else "")
    return ["", f"Where the learners converged to turn-taking in a team of odd size, modal in one of its two middle "
                f"states ({runs}), they spend at least {min(lows):.1f} % of the stable period in each of the two, "
                f"whose shares differ by {_span(gaps)} points: their modal state is a near tie, and the model names it "
                f"at {sum(t['modal'] for t in odd)} of {len(odd)}{expected}{beside}."]


def no_check_note(converged: bool, factor: float) -> str:
    """Why a learners' run beside a prediction is no check of it, in brackets; "" where it is one:
    the learners converged, at the horizon every check is at (`analysis.turn_taking.HORIZON`)."""
    if not converged:
        return " (not a check: the learners did not converge)"
    return "" if factor == HORIZON else f" (not a check: at {factor:g}x; the checks are at {HORIZON:g}x)"


def trials_words(learners: dict) -> str:
    """A learners' run's trials, with its horizon where it is not the checks' (`no_check_note`)."""
    return f"{learners['trials']} trials" + ("" if learners["factor"] == HORIZON else f", {learners['factor']:g}x")


def support_of(learners: dict, state: str) -> float:
    """In what share of resamples of the learners' trials `state` is their modal state
    (`analysis.turn_taking.modal_support`); NaN where their run has no table of its trials, or
    where their modal state is one that table has no column for (a state outside the team's)."""
    stats = learners["trial_stats"]
    if not len(stats) or STATE_PREFIX + learners["modal_state"] not in stats.columns:
        return math.nan
    return modal_support(stats, state)


def model_support(where: Path, predicted: dict) -> float:
    """How firmly the turn-taking model names its modal state, where it takes that state from
    static alternators (`files.model_alternators`): the share of resamples of the alternators'
    trials (their run's `trial_stats.csv`, checked with the report's other runs) in which the
    predicted state is theirs. NaN where the state is the surrogate learners' own, or the
    alternators' table is missing."""
    run = model_alternators(where, predicted)
    if run is None or not (run / "trial_stats.csv").is_file():
        return math.nan
    # only the alternators' own rows (a baseline's trials may sit beside them); a table without its
    # columns is one line naming it, as a damaged one is
    return read_or_refuse(run / "trial_stats.csv", lambda p: modal_support(
        pd.read_csv(p), str(predicted["modal_state"]), controller=ALTERNATOR))


def tally_line(tallies: list[dict]) -> list[str]:
    """Over the rows whose learners converged: in how many each model names their regime, and
    the turn-taking model their modal state; where the learners' trials have a table, the hits
    expected over resamples of them, what a prediction of each run's own modal state would get,
    and the hits at the points whose trials name their modal state firmly (`FIRM`)."""
    checks = [t for t in tallies if t["check"]]
    if not checks:
        return []
    turn = [t for t in checks if "modal" in t]
    drift = [t for t in checks if "drift" in t]
    resampled = [t for t in turn if math.isfinite(t.get("support", math.nan))]
    which = "" if len(resampled) == len(turn) else " with a table of their trials"
    # a firm point counts whatever the predicted state's support (NaN compares False: no table, no firm point)
    named = [t for t in turn if t.get("ceiling", math.nan) >= FIRM]
    firm = (f" (over resamples of the learners' trials, in {sum(t['support'] for t in resampled):.1f} of the "
            f"{len(resampled)}{which} on average, where a prediction of each run's own modal state would be right "
            f"in {sum(t['ceiling'] for t in resampled):.1f}; at the {len(named)} whose trials name their own modal "
            f"state firmly, modal in at least {100 * FIRM:.0f} % of resamples, in {sum(t['modal'] for t in named)})"
            if resampled else "")
    words = [f"the turn-taking model names their modal state in {sum(t['modal'] for t in turn)} of {len(turn)}"
             f"{firm} and their regime in {sum(t['regime'] for t in turn)}"] if turn else []
    if drift:
        words.append(f"the drift model their regime in {sum(t['drift'] for t in drift)} of {len(drift)}")
    runs = f"{len(checks)} run" + ("s" if len(checks) != 1 else "")
    return ["", f"Where the learners converged ({runs}): " + "; ".join(words) + "."]


def switches_of(predicted: dict) -> str:
    """How a turn-taking prediction's lone switchers were measured (`surrogate.switches`, which
    `turn_taking.json` records); a prediction that records none predates the choice: alternators."""
    return str(predicted.get("switches", ALTERNATORS))


def switches_line(explored: list[dict], main: list[dict]) -> list[str]:
    """The tally of the predictions whose lone switchers were measured from explorers
    (`switches_of`), beside the model as it is at the same learners' runs (each tally's `run`)."""
    return beside_line("With lone switchers measured from explorers (`surrogate.switches=explorers`, predictions "
                       f"`*{EXPLORED}`)", explored, main)


def post_hoc_line(post: list[dict], main: list[dict]) -> list[str]:
    """The tally of the predictions made after the learners' runs beside them were read (folders
    ending in `POST_HOC`), beside the model as it is at the same runs: diagnostics, never checks."""
    return beside_line(f"Made after the learners' runs beside them were read (predictions `*{POST_HOC}`, by a way of "
                       "the model built after those runs were read: diagnostics, not checks)", post, main)


def beside_line(lead: str, these: list[dict], main: list[dict]) -> list[str]:
    """Over the rows of `these` whose learners converged, in how many the turn-taking model names
    the learners' modal state and regime; beside it, the same counts of `main` at the same runs."""
    if not these:
        return []
    checks = [t for t in these if t["check"]]
    if not checks:
        return ["", f"{lead}: no run beside them converged ({len(these)} in all)."]
    same = {t["run"]: t for t in main if t["check"]}
    paired = [same[t["run"]] for t in checks if t["run"] in same]
    runs = f"{len(checks)} run" + ("s" if len(checks) != 1 else "")
    beside = (f"; the model as it is, at {len(paired)} of the same runs, their modal state in "
              f"{sum(t['modal'] for t in paired)} and their regime in {sum(t['regime'] for t in paired)}"
              if paired else "")
    return ["", f"{lead}, where the learners converged ({runs}): the turn-taking model names their modal state in "
                f"{sum(t['modal'] for t in checks)} of {len(checks)} and their regime in "
                f"{sum(t['regime'] for t in checks)}{beside}."]
