"""Section 1.5.5, "initial task distribution": six identical TAVC learners on two crossing
circuits settle into the allocation the vacancy-chain model predicts (Table 1.2, Figures 1.6
and 1.7). The chapter's base case."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="initial_distribution",
    section="1.5.5",
    order=20,
    state_table="1.2",
    state_figure="1.6",
    performance_figure="1.7",
    chapter_trials=(20, 20),
    base_case=True,
    compare=True,
    surrogate=True,
    claims=(
        Claim(3, "\"the increase in the amount of time spent in state 3 : 3 is statistically significant\" (over "
                 "random), and the time in 3:3 is \"significantly higher than the time spent in any of the other "
                 "states\".",
              "tavc_cli.analysis.claim_rules:claim_3",
              on_tables="tavc_cli.analysis.chapter_checks:claim_3"),
        Claim(4, "the random controllers' distribution is \"closely aligned with this theoretical estimate\" (the "
                 "binomial row), \"though the differences are statistically significant\".",
              "tavc_cli.analysis.claim_rules:claim_4",
              on_tables="tavc_cli.analysis.chapter_checks:claim_4"),
        Claim(5, "the learners' performance is \"significantly higher than the performance of random allocation\".",
              "tavc_cli.analysis.claim_rules:claim_5"),
    ),
)
