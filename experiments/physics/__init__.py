"""The physical grasp study: does S_G predict whether the simulated hand holds a block? Hand
placement, one grasp's physical test, the pooled report (``python -m experiments.physics``)."""
