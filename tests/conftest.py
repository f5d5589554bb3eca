"""Test-wide settings: headless rendering through EGL before anything imports MuJoCo."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
