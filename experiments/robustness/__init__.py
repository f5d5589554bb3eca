"""The robustness study: the task cycle on random scenes when the simulated world differs from
the robot's model (section 5.3's woes), per perturbation and scale (``python -m
experiments.robustness``; docs/robustness.md)."""
