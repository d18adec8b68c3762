"""Section 1.4.2: five robots on one circuit learn which transport behaviour to use in which
sensed state (Table 1.1 of traversal and target times; Figure 1.4's kind of target times)."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="spatiotemporal",
    section="1.4.2",
    order=10,
    time_table="1.1",
    kind_figures=("1.4",),
    learns="behaviours",
    claims=(
        Claim(1, "all mean traversal and target times are \"lower than the ones produced by the initial random "
                 "behavior application ... by a statistically significant amount\", at every row of Table 1.1.",
              "tavc_cli.analysis.claim_rules:claim_1"),
        Claim(2, "learned policies are \"dominated by the direct target approach behavior, but with significant "
                 "portions of the wall-following behavior\"; robots keep \"to the left side\"; the yellow "
                 "stop-rates are \"significantly lower\" than the stop-rate for robots seen from the front and "
                 "than the red and green stop-rates.",
              "tavc_cli.analysis.claim_rules:claim_2"),
    ),
)
