"""Trials from spec to record: building the specs, advancing batches of trials, storing and
reusing their records, and running them on the chosen executor."""
