"""Analysis of saved trial records: a run's tables, statistics and claim tests, computed from
the records alone (nothing here simulates)."""
