"""Section 1.6: three fast and three slow robots with softmax TAVC; the fast ones should take the
high-value circuit (Table 1.6; Figures 1.12 and 1.13, whose kind the report draws as f:s grids)."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="heterogeneous",
    section="1.6",
    order=60,
    state_table="1.6",
    kind_figures=("1.12", "1.13"),
    chapter_trials=(15, 15),
    compare=True,
    surrogate=True,
    claims=(
        Claim(9, "fast robots take the high-value circuit: \"the difference in time spent in state 0 : 3 is "
                 "statistically significant\" (3:0 by the chapter's table) and it \"stands out as the state with "
                 "the highest relative increase\"; performance is \"significantly higher\" than random's; fast "
                 "robots \"have higher estimated utilities\" for the high-value circuit, slow ones for the low, "
                 "and the mean difference is \"greater for the fast robots\".",
              "tavc_cli.analysis.claim_rules:claim_9",
              on_tables="tavc_cli.analysis.chapter_checks:claim_9"),
    ),
)
