"""Perturbations of the simulated world: the woes of section 5.3 ("imprecise object models,
discretization errors, calibration drifts, and kinematic model imprecision"), named, scaled and
drawn per episode from its seed.

The simulated world is the truth; a perturbation moves the truth away from the model the robot
believes (the nominal scene and robot), never the belief. Each named perturbation, at ``SCALE``
1, is:

- ``camera``: the overhead camera's true pose off its calibration by up to
  :data:`CAMERA_SHIFT` (a shift in a uniformly random direction, its length uniform) and
  :data:`CAMERA_TURN` (about a uniformly random axis);
- ``arm_base``: the arm's base off by up to :data:`ARM_BASE_SHIFT` (hand-eye calibration);
- ``kinematics``: joint encoder offsets up to :data:`ARM_ENCODER_OFFSET` (arm) and
  :data:`HAND_ENCODER_OFFSET` (fingers), each link :data:`LINK_LENGTH` longer or shorter
  (:data:`LINKS`);
- ``object``: each block's mass times a factor in :data:`MASS_FACTOR`, its friction and each
  pad's times one in :data:`FRICTION_FACTOR` (log-uniform: a factor and its inverse are
  equally likely);
- ``sensing``: noise on the tendon tensions (:data:`TENSION_NOISE`), the joint angles
  (:data:`ANGLE_NOISE`) and the overhead image (:data:`PIXEL_NOISE`, :data:`DEPTH_NOISE`, a blur
  of :data:`BLUR`); standard deviations, drawn afresh at every reading;
- ``actuation``: the tendon drive's lag (each actuator's time constant) and gains (each joint's
  stiffness and damping) times a factor in 1 +- :data:`ACTUATION_FACTOR`;
- ``woes``: all of them at once.

``SCALE`` multiplies every magnitude (a factor range's logarithm). Each perturbation is drawn
from its own generator, ``numpy.random.default_rng([seed, PERTURB_STREAM, k])`` (k its index in
:data:`KINDS`), as unit values then multiplied by the scale: no other random stream changes, a
perturbation's draw does not depend on which others are on, and the same seed at scale 2 is the
scale-1 draw doubled. How each is applied to the simulated world: :mod:`hand_sim.perturb_model`
(the model), :mod:`hand_sim.sensing` (the readings).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hand_sim import robot
from hand_sim.errors import HandSimError

#: Second word of every perturbation's seed sequence (section 5.3); the third is its index.
PERTURB_STREAM = 53
#: The perturbations, and the name of all of them at once.
KINDS: tuple[str, ...] = ("camera", "arm_base", "kinematics", "object", "sensing", "actuation")
WOES = "woes"
NAMES: tuple[str, ...] = (*KINDS, WOES)
#: ``--perturb none``: no perturbation (overrides a scene file's ``[perturb]`` table).
NONE = "none"
#: Largest SCALE (at 5, a gain factor of 1 - 5 x 0.2 would be 0).
MAX_SCALE = 4.0

# --- magnitudes at SCALE 1 ------------------------------------------------------------------
CAMERA_SHIFT = 0.010  #: m
CAMERA_TURN = math.radians(1.0)  #: rad
ARM_BASE_SHIFT = 0.005  #: m
ARM_ENCODER_OFFSET = math.radians(0.5)  #: rad, each arm joint
HAND_ENCODER_OFFSET = math.radians(1.0)  #: rad, each finger joint
LINK_LENGTH = 0.002  #: m, each link of :data:`LINKS`
MASS_FACTOR = (0.5, 2.0)
FRICTION_FACTOR = (0.6, 1.2)
#: Tension noise: 2 % of the reading plus 0.1 N (standard deviation).
TENSION_NOISE = (0.02, 0.1)
ANGLE_NOISE = math.radians(0.1)  #: rad, every joint angle read
#: The overhead image: colour noise (grey levels of 255), depth noise (m) and a Gaussian blur
#: (pixels of the 1920x1440 image; 1 px is 0.54 mm on the blocks' tops). Section
#: 5.3 names no values: these are a good industrial camera's (docs/robustness.md).
PIXEL_NOISE = 4.0
DEPTH_NOISE = 0.001
BLUR = 1.0
ACTUATION_FACTOR = 0.2

#: The links whose lengths ``kinematics`` changes: (model, body, axis) -- the body's offset from
#: its parent along ``axis`` (0 x, 1 y, 2 z) is the link's length. The arm: the shoulder above
#: the waist, the upper arm, the forearm, the wrist to the flange; each finger: its proximal and
#: middle phalanges.
LINKS: tuple[tuple[str, str, int], ...] = (
    ("arm", "upper_arm", 2),
    ("arm", "forearm", 2),
    ("arm", "wrist", 2),
    ("arm", "flange", 2),
    *(("hand", f"{f}_{link}", 1) for f in robot.FINGERS for link in ("middle", "distal")),
)


class PerturbError(HandSimError, ValueError):
    """A perturbation asked for that does not exist or has a bad scale; the message names the
    valid ones."""


def _valid_text() -> str:
    return f"valid: {', '.join(NAMES)} (each NAME or NAME=SCALE, SCALE 0..{MAX_SCALE:g}), or {NONE}"


@dataclass(frozen=True)
class PerturbSpec:
    """Which perturbations an episode runs with and at what scale: (kind, scale) pairs in
    :data:`KINDS` order, ``woes`` expanded; empty when unperturbed."""

    scales: tuple[tuple[str, float], ...] = ()

    @classmethod
    def of(cls, asked: Mapping[str, float]) -> PerturbSpec:
        """From ``{name: scale}`` (names of :data:`NAMES`): ``woes`` sets every kind, a kind
        named beside it keeps its own scale. Raises :class:`PerturbError`."""
        out: dict[str, float] = {}
        for name, scale in asked.items():
            if name not in NAMES:
                raise PerturbError(f"unknown perturbation {name!r}; {_valid_text()}")
            value = float(scale)
            if not (math.isfinite(value) and 0.0 <= value <= MAX_SCALE):
                raise PerturbError(
                    f"{name}: scale must be a number from 0 to {MAX_SCALE:g}, got {scale!r}"
                )
            if name == WOES:
                for kind in KINDS:
                    out.setdefault(kind, value)
            else:
                out[name] = value
        if WOES in asked:  # a kind named beside woes keeps its own scale, in any order
            out.update({k: float(v) for k, v in asked.items() if k != WOES})
        return cls(tuple((k, out[k]) for k in KINDS if k in out))

    @classmethod
    def parse(cls, text: str) -> PerturbSpec:
        """``NAME[=SCALE],...`` (SCALE 1 when left out), or ``none``."""
        text = text.strip()
        if text == NONE:
            return cls()
        asked: dict[str, float] = {}
        for part in text.split(","):
            name, eq, value = part.strip().partition("=")
            name = name.strip()
            if not name:
                raise PerturbError(f"empty name in {text!r}; {_valid_text()}")
            if name in asked:
                raise PerturbError(f"{name} is named twice in {text!r}")
            try:
                scale = float(value) if eq else 1.0
            except ValueError:
                scale = math.nan
            if not (math.isfinite(scale) and 0.0 <= scale <= MAX_SCALE):
                raise PerturbError(
                    f"{name}: scale must be a number from 0 to {MAX_SCALE:g}, got {value.strip()!r}"
                )
            asked[name] = scale
        return cls.of(asked)

    def scale(self, kind: str) -> float:
        """The scale of ``kind`` (0: not perturbed)."""
        return dict(self.scales).get(kind, 0.0)

    @property
    def active(self) -> bool:
        """Whether anything is perturbed (a kind at scale 0 perturbs nothing)."""
        return any(s > 0.0 for _, s in self.scales)

    def text(self) -> str:
        """The ``--perturb`` value that asks for this spec (``none`` when empty)."""
        if not self.scales:
            return NONE
        return ",".join(f"{k}={s:g}" for k, s in self.scales)


def _unit_ball(rng: np.random.Generator) -> NDArray[np.float64]:
    """A vector in the unit ball: a uniformly random direction, its length uniform in [0, 1]."""
    v = rng.normal(size=3)
    return v / np.linalg.norm(v) * rng.uniform(0.0, 1.0)


def _log_factors(rng: np.random.Generator, bounds: tuple[float, float], n: int) -> NDArray:
    """``n`` unit draws of log factors in ``[log lo, log hi]`` (scaled by the caller)."""
    return rng.uniform(math.log(bounds[0]), math.log(bounds[1]), n)


@dataclass(frozen=True, eq=False)
class Perturbation:
    """One episode's drawn perturbation (:func:`draw`); the unperturbed values where a kind is
    off. Block values are keyed by block name; arrays follow :data:`robot.ARM_JOINTS`,
    :data:`robot.HAND_JOINTS`, :data:`robot.FINGERS` and :data:`LINKS`."""

    spec: PerturbSpec
    #: the episode's seed (a sequence of them for a study's grasp: its seed words)
    seed: int | tuple[int, ...]
    camera_shift: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))  #: m, world
    camera_turn: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))  #: rad, world
    arm_base_shift: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))  #: m
    arm_offsets: NDArray[np.float64] = field(default_factory=lambda: np.zeros(5))  #: rad
    hand_offsets: NDArray[np.float64] = field(default_factory=lambda: np.zeros(16))  #: rad
    link_deltas: NDArray[np.float64] = field(default_factory=lambda: np.zeros(len(LINKS)))  #: m
    mass_factors: dict[str, float] = field(default_factory=dict)
    friction_factors: dict[str, float] = field(default_factory=dict)
    pad_friction_factors: NDArray[np.float64] = field(default_factory=lambda: np.ones(4))
    kp_factors: NDArray[np.float64] = field(default_factory=lambda: np.ones(16))
    kd_factors: NDArray[np.float64] = field(default_factory=lambda: np.ones(16))
    lag_factors: NDArray[np.float64] = field(default_factory=lambda: np.ones(32))

    @property
    def sensing(self) -> float:
        """The scale of the sensing noise (0: exact readings)."""
        return self.spec.scale("sensing")

    @property
    def perturbs_object(self) -> bool:
        return self.spec.scale("object") > 0.0

    def mass_factor(self, block: str) -> float:
        return self.mass_factors.get(block, 1.0)

    def friction_factor(self, block: str) -> float:
        return self.friction_factors.get(block, 1.0)

    def noise_generator(self) -> np.random.Generator:
        """The generator of the sensing noise, drawn as the episode reads its sensors."""
        return np.random.default_rng([*_words(self.seed), PERTURB_STREAM, len(KINDS)])

    def to_json(self) -> dict[str, Any]:
        """What summary.json records: the perturbations asked for, their scales, and what was
        drawn (SI units; angles also in degrees)."""
        s = self.spec

        def r(a: Any, n: int = 6) -> Any:
            return np.round(np.asarray(a, dtype=float), n).tolist()

        seed = self.seed if isinstance(self.seed, int) else list(self.seed)
        out: dict[str, Any] = {"asked": s.text(), "scales": dict(s.scales), "seed": seed}
        if s.scale("camera"):
            out["camera"] = {
                "shift_m": r(self.camera_shift),
                "turn_rad": r(self.camera_turn),
                "shift_mm": round(float(np.linalg.norm(self.camera_shift)) * 1000, 3),
                "turn_deg": round(math.degrees(float(np.linalg.norm(self.camera_turn))), 4),
            }
        if s.scale("arm_base"):
            out["arm_base"] = {"shift_m": r(self.arm_base_shift)}
        if s.scale("kinematics"):
            out["kinematics"] = {
                "arm_offsets_deg": r(np.degrees(self.arm_offsets), 4),
                "hand_offsets_deg": r(np.degrees(self.hand_offsets), 4),
                "link_deltas_mm": {
                    f"{m}/{b}": round(float(d) * 1000, 4)
                    for (m, b, _), d in zip(LINKS, self.link_deltas, strict=True)
                },
            }
        if s.scale("object"):
            out["object"] = {
                "mass_factors": {k: round(v, 4) for k, v in self.mass_factors.items()},
                "friction_factors": {k: round(v, 4) for k, v in self.friction_factors.items()},
                "pad_friction_factors": r(self.pad_friction_factors, 4),
            }
        if s.scale("sensing"):
            out["sensing"] = {
                "tension_sigma": f"{TENSION_NOISE[0] * s.scale('sensing') * 100:g} % + "
                f"{TENSION_NOISE[1] * s.scale('sensing'):g} N",
                "angle_sigma_deg": math.degrees(ANGLE_NOISE) * s.scale("sensing"),
                "pixel_sigma": PIXEL_NOISE * s.scale("sensing"),
                "depth_sigma_m": DEPTH_NOISE * s.scale("sensing"),
                "blur_px": BLUR * s.scale("sensing"),
            }
        if s.scale("actuation"):
            out["actuation"] = {
                "kp_factors": r(self.kp_factors, 4),
                "kd_factors": r(self.kd_factors, 4),
                "lag_factors": r(self.lag_factors, 4),
            }
        return out


def _words(seed: int | Sequence[int]) -> tuple[int, ...]:
    return (int(seed),) if isinstance(seed, int | np.integer) else tuple(int(s) for s in seed)


def generator(seed: int | Sequence[int], kind: str) -> np.random.Generator:
    """The generator ``kind`` is drawn from for an episode of ``seed`` (an integer, or the seed
    words of a study's grasp)."""
    return np.random.default_rng([*_words(seed), PERTURB_STREAM, KINDS.index(kind)])


def draw(spec: PerturbSpec, seed: int | Sequence[int], blocks: Sequence[str]) -> Perturbation:
    """The perturbation ``spec`` asks for, drawn for an episode of ``seed`` whose scene holds
    ``blocks`` (names, in the scene's order)."""
    values: dict[str, Any] = {}
    n_arm, n_hand = len(robot.ARM_JOINTS), len(robot.HAND_JOINTS)
    for kind, scale in spec.scales:
        rng = generator(seed, kind)
        if kind == "camera":
            values["camera_shift"] = CAMERA_SHIFT * scale * _unit_ball(rng)
            values["camera_turn"] = CAMERA_TURN * scale * _unit_ball(rng)
        elif kind == "arm_base":
            values["arm_base_shift"] = ARM_BASE_SHIFT * scale * _unit_ball(rng)
        elif kind == "kinematics":
            values["arm_offsets"] = ARM_ENCODER_OFFSET * scale * rng.uniform(-1, 1, n_arm)
            values["hand_offsets"] = HAND_ENCODER_OFFSET * scale * rng.uniform(-1, 1, n_hand)
            values["link_deltas"] = LINK_LENGTH * scale * rng.uniform(-1, 1, len(LINKS))
        elif kind == "object":
            mass = np.exp(scale * _log_factors(rng, MASS_FACTOR, len(blocks)))
            friction = np.exp(scale * _log_factors(rng, FRICTION_FACTOR, len(blocks)))
            pads = np.exp(scale * _log_factors(rng, FRICTION_FACTOR, len(robot.FINGERS)))
            values["mass_factors"] = {b: float(m) for b, m in zip(blocks, mass, strict=True)}
            values["friction_factors"] = {
                b: float(f) for b, f in zip(blocks, friction, strict=True)
            }
            values["pad_friction_factors"] = pads
        elif kind == "actuation":
            spread = ACTUATION_FACTOR * scale
            values["kp_factors"] = 1.0 + spread * rng.uniform(-1, 1, n_hand)
            values["kd_factors"] = 1.0 + spread * rng.uniform(-1, 1, n_hand)
            values["lag_factors"] = 1.0 + spread * rng.uniform(-1, 1, 2 * n_hand)
        # sensing draws its noise as the sensors are read (Perturbation.noise_generator)
    words = _words(seed)
    return Perturbation(spec=spec, seed=words[0] if len(words) == 1 else words, **values)


def for_episode(
    spec: PerturbSpec, seed: int | Sequence[int], blocks: Sequence[str]
) -> Perturbation | None:
    """The perturbation of an episode of ``seed`` (scene blocks ``blocks``), or None when
    ``spec`` perturbs nothing: the world is then the nominal one, exactly as built without
    perturbations."""
    return draw(spec, seed, blocks) if spec.active else None
