"""A fast surrogate of the learning dynamics, calibrated from the physical simulator.

The chapter's learners meet the world only through the time each task takes: a robot picks
a circuit, the task takes t seconds, it earns w / t. The surrogate keeps the learners exactly
(the same policy classes, seeds, events and trial records as `tavc run`) and replaces the
physical world by draws of whole tasks measured in it: each task's time (and where it went:
driving, avoiding, waiting...) is drawn from the tasks the simulator measured with static
controllers in the same make-up of the group (`tasks`): how many robots of each group stay on
each circuit, how many alternate, and whether this task stays or switches. What it leaves out:
where the robots are, the order in which they arrive, and how a task's time depends on the
make-up changing while it runs; `docs/surrogate.md` says when that matters.

- `tasks`: the compositions, the static runs that measure them, the table of measured tasks.
- `engine`: one trial, event by event, into the simulator's `TrialRecord`.
- `run`: a run of an experiment on the surrogate, with the same tables as `tavc run`.
"""
