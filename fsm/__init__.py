"""The task cycle of section 5.2 (Figure 14): a finite state machine that sequences Select/Model,
Coarse Reach, Fine Reach, Posture Control, Wrench Closure, Grasp Object and Deliver on the
simulated arm and hand, and records the episode. ``python -m fsm.run --scene clutter3``."""

# hand_sim picks MuJoCo's headless GL backend (MUJOCO_GL=egl) when imported: before the first
# ``import mujoco`` of the task cycle's modules, so MuJoCo never loads GLFW (a display library,
# 0.2-0.4 s of start-up) that the renderer would then replace with EGL.
import hand_sim  # noqa: F401
