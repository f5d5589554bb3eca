"""The task cycle of section 5.2 (Figure 14): a finite state machine that sequences Select/Model,
Coarse Reach, Fine Reach, Posture Control, Wrench Closure, Grasp Object and Deliver on the
simulated arm and hand, and records the episode. ``python -m fsm.run --scene clutter3``."""
