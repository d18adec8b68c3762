"""Section 1.5.5, breakdown without a vacancy: a robot on the low-value circuit breaks down, and
the allocation should not change (Table 1.4, Figure 1.10)."""

from tavc_cli.chapter.registry import Claim, Experiment

EXPERIMENT = Experiment(
    name="breakdown_no_vacancy",
    section="1.5.5",
    order=40,
    state_table="1.4",
    performance_figure="1.10",
    chapter_trials=(20, 0),
    compare=True,
    surrogate=True,
    claims=(
        Claim(7, "with a low-circuit robot removed the distribution \"was not significantly different\" from "
                 "breakdown's; performance \"fell significantly when the robot was removed\" and \"remained "
                 "significantly higher\" than random's, with \"no significant difference\" from breakdown's stable "
                 "period nor between the convergence and stable periods.",
              "tavc_cli.analysis.claim_rules:claim_7", against="breakdown",
              on_tables="tavc_cli.analysis.chapter_checks:claim_7"),
    ),
)
