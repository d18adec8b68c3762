"""Section 1.5.5, "vacancy from robot breakdown": a robot on the high-value circuit breaks down
in a converged group and a low-circuit robot fills the vacancy (Table 1.3, Figures 1.8 and 1.9)."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="breakdown",
    section="1.5.5",
    order=30,
    state_table="1.3",
    state_figure="1.8",
    performance_figure="1.9",
    # the chapter gives no count of its random trials here; read as Table 1.2's 20
    chapter_trials=(20, 20),
    compare=True,
    surrogate=True,
    vacancy=True,
    claims=(
        Claim(6, "after a high-circuit robot breaks down the learners keep 3:2 \"for a significantly larger amount "
                 "of time than a group of five random controllers\", and their performance is \"significantly "
                 "higher\" than random's and than a static allocation \"optimized for six robots\".",
              "tavc_cli.analysis.claim_rules:claim_6",
              on_tables="tavc_cli.analysis.chapter_checks:claim_6"),
    ),
)
