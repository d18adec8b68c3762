"""How a state label is read back wherever tavc reads one (`tavc_cli.notation`)."""

import numpy as np
import pandas as pd
import pytest

from tavc_cli.analysis.value_ratio import high_share
from tavc_cli.compare.metrics import fast_share
from tavc_cli.notation import column_state, counts_of, high_of, join_counts, state_counts


@pytest.mark.parametrize(("label", "counts"), [
    ("3:2", (3, 2)), ("0:6", (0, 6)), ("10:0:2", (10, 0, 2)), ("3", (3,)),
])
def test_a_state_reads_as_its_numbers_in_order(label, counts):
    assert state_counts(label) == counts
    assert counts_of(label) == counts
    assert high_of(label) == counts[0]
    assert join_counts(counts) == label


@pytest.mark.parametrize("label", ["3:-1", "3.0:2", " 3:2", "3:", ":", "", "a:b", "\u00b3:3", "\u0663:3",
                                   None, 3, (3, 2), "9" * 10 + ":3", "9" * 5000 + ":3"])
def test_anything_but_ascii_digits_joined_by_colons_is_no_state(label):
    assert state_counts(label) is None
    if isinstance(label, str):
        with pytest.raises(ValueError, match="is not a state"):
            counts_of(label)


def test_counts_are_written_as_integers_whatever_their_type():
    assert join_counts(np.array([4, 1], dtype=np.int64)) == "4:1"
    assert join_counts([]) == ""


def test_share_columns_name_their_state_and_other_columns_none():
    assert column_state("pct_3:2") == "3:2"
    assert column_state("q_gap_fast") is None and column_state("trial") is None


def test_the_readers_of_share_columns_weigh_each_state_by_its_first_number():
    # two trials: 60 % in 3:2 and 40 % in 2:3; then 100 % in 3:0 (after two robots broke down)
    stats = pd.DataFrame({"trial": [0, 1], "pct_3:2": [60.0, 0.0], "pct_2:3": [40.0, 0.0], "pct_3:0": [0.0, 100.0],
                          "q_gap_fast": [9.0, 9.0]})
    # the high-value circuit's share of the team: 0.6 * 3/5 + 0.4 * 2/5 = 0.52, then 3/3 = 1
    assert high_share(stats) == pytest.approx([0.52, 1.0])
    # read as groups (fast:slow on the high-value circuit), three fast robots: (60 * 3 + 40 * 2) / 100 / 3, then 1
    assert fast_share(stats, 3) == pytest.approx([260 / 300, 1.0])
