"""Section 1.5.5, "changing sub-task values": five robots, then the circuits swap values and a
robot migrates to fill the new vacancy (Table 1.5, Figure 1.11)."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="value_change",
    section="1.5.5",
    order=50,
    state_table="1.5",
    performance_figure="1.11",
    chapter_trials=(20, 0),
    compare=True,
    surrogate=True,
    vacancy=True,
    claims=(
        Claim(8, "after the values swap 3:2 and 4:1 are \"significantly higher\" than after breakdown; against "
                 "random the learners have \"a significantly higher value for state 3 : 2 and significantly lower "
                 "values for all other states\"; performance \"fell significantly\", then came back to a level "
                 "\"not significantly different from the initial level\".",
              "tavc_cli.analysis.claim_rules:claim_8", against="breakdown",
              on_tables="tavc_cli.analysis.chapter_checks:claim_8"),
    ),
)
