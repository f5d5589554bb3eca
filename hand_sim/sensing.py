"""What the robot's sensors read from the simulated world: its joint encoders, tendon tension
sensors and overhead camera, with the episode's perturbation (:mod:`hand_sim.perturb`): encoder
offsets (``kinematics``) and noise (``sensing``). Unperturbed, every reading is the simulation's
value itself, bit for bit, and no random number is drawn.

The robot's software reads the world through these (section 5.3: the real system ran "in the
presence of woes that plague every real world implementation"); the simulation's own state is
for the physics, the rendering and the judge. A joint servo closes its loop on its encoder, so
a commanded angle q puts the joint at q minus the encoder's offset
(:meth:`hand_sim.world.World.set_arm_targets`). Noise is drawn afresh at every reading, from the
perturbation's own generator (:meth:`~hand_sim.perturb.Perturbation.noise_generator`): an
episode reads its sensors in the same order every time it runs, so it draws the same noise.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hand_sim.perturb import (
    ANGLE_NOISE,
    BLUR,
    DEPTH_NOISE,
    PIXEL_NOISE,
    TENSION_NOISE,
    Perturbation,
)


class _Simulated(Protocol):
    """What the sensors read the truth from (a :class:`hand_sim.world.World`)."""

    def arm_qpos(self) -> NDArray[np.float64]: ...
    def hand_qpos(self) -> NDArray[np.float64]: ...
    def hand_tensions(self) -> NDArray[np.float64]: ...
    def wrist_readings(self) -> NDArray[np.float64]: ...


class Sensors:
    """The readings of one world's sensors (``world.sensors``): exact when ``perturbation`` is
    None, else with its offsets and noise."""

    def __init__(self, world: _Simulated, perturbation: Perturbation | None) -> None:
        self._world = world
        self.perturbation = perturbation
        #: scale of the noise (0: none)
        self.noise = 0.0 if perturbation is None else perturbation.sensing
        self._rng = None if perturbation is None else perturbation.noise_generator()
        zeros5, zeros16 = np.zeros(5), np.zeros(16)
        #: encoder offsets (rad): what each encoder reads minus the joint's true angle
        self.arm_offsets = zeros5 if perturbation is None else perturbation.arm_offsets
        self.hand_offsets = zeros16 if perturbation is None else perturbation.hand_offsets

    @property
    def exact(self) -> bool:
        """Whether every reading is the simulation's own value."""
        return self.perturbation is None

    def _gauss(self, sigma: float | NDArray[np.float64], shape: tuple[int, ...]) -> NDArray:
        assert self._rng is not None
        return self._rng.normal(0.0, 1.0, shape) * sigma

    def _angles(self, true: NDArray[np.float64], offsets: NDArray[np.float64]) -> NDArray:
        if self.exact:
            return true
        out = true + offsets
        if self.noise:
            out = out + self._gauss(ANGLE_NOISE * self.noise, true.shape)
        return out

    def arm_angles(self) -> NDArray[np.float64]:
        """(5,) the arm's encoders (rad), :data:`hand_sim.robot.ARM_JOINTS` order."""
        return self._angles(self._world.arm_qpos(), self.arm_offsets)

    def hand_angles(self) -> NDArray[np.float64]:
        """(16,) the hand's joint-angle sensors (rad), :data:`hand_sim.robot.HAND_JOINTS`
        order."""
        return self._angles(self._world.hand_qpos(), self.hand_offsets)

    def tensions(self) -> NDArray[np.float64]:
        """(16, 2) the tendon tension sensors (N; flexor, extensor), with noise of
        :data:`~hand_sim.perturb.TENSION_NOISE` (a share of the reading plus a floor)."""
        true = self._world.hand_tensions()
        if not self.noise:
            return true
        rel, floor = TENSION_NOISE
        sigma = self.noise * (rel * np.abs(true) + floor)
        return true + self._gauss(sigma, true.shape)

    def wrist(self) -> NDArray[np.float64]:
        """(9,) the wrist's force (N), torque (N m) and accelerometer (m/s^2) readings in the
        sensors' own frame (not perturbed: section 5.3 names no wrist sensor's woe)."""
        return self._world.wrist_readings()

    def image(
        self, rgb: NDArray[np.uint8], depth: NDArray[np.float32]
    ) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
        """The overhead camera's images as its sensor delivers them: blurred by
        :data:`~hand_sim.perturb.BLUR` (the optics), then colour noise
        :data:`~hand_sim.perturb.PIXEL_NOISE` (grey levels, rounded and clipped to 0-255) and
        depth noise :data:`~hand_sim.perturb.DEPTH_NOISE` (m) on every pixel."""
        if not self.noise:
            return rgb, depth
        import cv2

        sigma = BLUR * self.noise
        colour = cv2.GaussianBlur(rgb.astype(np.float32), (0, 0), sigma)
        colour += self._gauss(PIXEL_NOISE * self.noise, colour.shape).astype(np.float32)
        noisy_rgb = np.clip(np.rint(colour), 0, 255).astype(np.uint8)
        noise = self._gauss(DEPTH_NOISE * self.noise, depth.shape).astype(np.float32)
        return noisy_rgb, (depth + noise).astype(np.float32)
