"""The task-cycle bench: many seeded episodes of the task cycle in parallel (processes here, or a
Ray cluster), their success rate, failures and timings (``python -m experiments.bench``)."""
