"""The simulated world of graspsim: scenes, MuJoCo model assembly, camera and rerun recorder.

Section 5 of Coelho & Grupen describes the physical setup reproduced here: a GE P50 arm carrying a
Utah/MIT hand above a table of 20 cm wooden prism blocks, watched by an overhead camera.

Importing this package sets ``MUJOCO_GL=egl`` unless the caller chose another backend, so that
rendering works headless on a CPU-only machine.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from hand_sim.errors import HandSimError, SceneError, SimulationError

__all__ = ["HandSimError", "SceneError", "SimulationError"]
