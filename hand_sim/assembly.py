"""Assembly of the world's MJCF (section 5, Figure 13): floor, table, the GE P50-style arm with the
Utah/MIT-style hand on its flange, one prism per block, a light and the overhead camera, joined with
``dm_control.mjcf`` from the models in ``models/``.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
from dm_control import mjcf

from hand_sim import robot
from hand_sim.blocks import add_block
from hand_sim.errors import SimulationError
from hand_sim.perturb import Perturbation
from hand_sim.resources import models_dir
from hand_sim.scene_spec import Scene, TableSpec
from hand_sim.tendon_drive import SERVO_KP

#: Directory of the MJCF models (hand.xml, arm.xml, table.xml), found by :mod:`hand_sim.resources`.
MODELS_DIR = models_dir()
ARM_XML, HAND_XML, TABLE_XML = "arm.xml", "hand.xml", "table.xml"
#: The hands the arm can carry (``World.build(hand=...)``, ``fsm.run --hand``): "servo", the
#: generic hand of models/hand.xml with 16 position servos; "tendon", the Utah/MIT hand as built
#: (models/utah_mit_hand/), 32 pull-only tendons driven by :mod:`hand_sim.tendon_drive`, the
#: default (docs/models.md, "The default hand").
HAND_XMLS: dict[str, str] = {"servo": HAND_XML, "tendon": "utah_mit_hand/utah_mit_hand.xml"}
HAND_KINDS: tuple[str, ...] = tuple(HAND_XMLS)
DEFAULT_HAND = "tendon"
#: Actuator group of the tendon hand's 16 joint-target registers (:func:`_add_target_registers`),
#: disabled in the world's options so that they exert no force.
TARGET_REGISTER_GROUP = 5
#: Model name given to the attached table (its names get the prefix ``table/``).
TABLE_MODEL = "table"
#: Largest allowed difference (m) between the scene's table height and the table model's top.
TABLE_HEIGHT_TOLERANCE = 1e-3
#: The floor (z = 0) that the arm and table stand on and that catches dropped blocks.
FLOOR_NAME = "floor"
FLOOR_HALF_SIZE = 3.0
FLOOR_RGBA = (0.3, 0.3, 0.33, 1.0)
#: Visual-only top drawn when the table model's top is not visible (thickness m, light wood rgba).
TABLE_VISUAL_NAME = "table_top_visual"
TABLE_VISUAL_THICKNESS = 0.01
TABLE_VISUAL_RGBA = (0.62, 0.55, 0.45, 1.0)

#: Physics options (docs/world.md): 2 ms step, implicit-fast integration for the stiff finger
#: servos (Euler lets low-inertia finger joints go NaN), elliptic friction cones with a high
#: impratio so that grasps do not slip.
TIMESTEP = 0.002
INTEGRATOR = "implicitfast"
CONE = "elliptic"
IMPRATIO = 10.0
#: MuJoCo's soft contacts let a held object creep: under its weight a grasped block turns
#: steadily in the fingers (6 deg in 2 s) until it falls. The noslip solver's post-processing of
#: the friction forces stops the creep (docs/models.md).
NOSLIP_ITERATIONS = 5

#: World position (x, y, z) of the arm's base frame: beside the table's -x edge, on the floor.
ARM_BASE_POSITION = (-0.60, 0.0, 0.0)
#: Yaw (rad) of the arm's base: its x axis points over the table.
ARM_BASE_YAW = 0.0

#: Overhead camera: name, vertical field of view (deg, MuJoCo's ``fovy``) and the image aspect
#: ratio it is sized for (the table must fill no more than CAMERA_FILL of the image).
CAMERA_NAME = "overhead"
CAMERA_FOVY_DEG = 45.0
CAMERA_ASPECT = 4.0 / 3.0
CAMERA_FILL = 0.95
#: Lighting (rgb): MuJoCo's camera headlight, dimmed, and one directional light from above.
HEADLIGHT_AMBIENT, HEADLIGHT_DIFFUSE = (0.3, 0.3, 0.3), (0.3, 0.3, 0.3)
LIGHT_DIFFUSE = (0.5, 0.5, 0.5)
#: Largest offscreen image the model allows (pixels).
MAX_RENDER_WIDTH, MAX_RENDER_HEIGHT = 1920, 1440


def camera_height_above_table(size_xy: tuple[float, float]) -> float:
    """Height (m) above the table top at which the overhead camera sees the whole top."""
    half_tan = math.tan(math.radians(CAMERA_FOVY_DEG) / 2.0)
    need_y = 0.5 * size_xy[1] / (half_tan * CAMERA_FILL)
    need_x = 0.5 * size_xy[0] / (half_tan * CAMERA_ASPECT * CAMERA_FILL)
    return max(need_x, need_y)


def build_mjcf(
    scene: Scene,
    *,
    with_robot: bool = True,
    models_dir: Path = MODELS_DIR,
    hand: str = DEFAULT_HAND,
    perturbation: Perturbation | None = None,
) -> tuple[mjcf.RootElement, dict[str, float]]:
    """The root MJCF element of ``scene`` and the arm's ``home`` posture (joint name -> rad; empty
    without the robot). The arm stands at :data:`ARM_BASE_POSITION`, the ``hand`` (one of
    :data:`HAND_KINDS`) on its ``attachment_site``, the blocks on the table top; ``perturbation``
    moves the world away from that nominal model (:mod:`hand_sim.perturb_model`)."""
    if hand not in HAND_XMLS:
        raise SimulationError(f"unknown hand {hand!r}; valid: {', '.join(HAND_KINDS)}")
    root = _new_root(scene.name)
    _add_table(root, scene.table, models_dir)
    _add_light_and_camera(root, scene.table)
    home = _add_robot(root, models_dir, hand) if with_robot else {}
    for block in scene.blocks:
        add_block(root, block, scene.table.height)
    if perturbation is not None:
        from hand_sim.perturb_model import apply_to_mjcf

        apply_to_mjcf(
            root, perturbation, with_robot=with_robot, hand=hand, blocks=scene.block_names
        )
    return root, home


def _new_root(name: str) -> mjcf.RootElement:
    """An empty world with the physics and rendering options, and the floor."""
    root = mjcf.RootElement(model=f"graspsim_{name}")
    root.compiler.angle = "radian"
    root.option.timestep = TIMESTEP
    root.option.integrator = INTEGRATOR
    root.option.cone = CONE
    root.option.impratio = IMPRATIO
    root.option.noslip_iterations = NOSLIP_ITERATIONS
    visual_global = getattr(root.visual, "global")  # "global" is a Python keyword
    visual_global.offwidth, visual_global.offheight = MAX_RENDER_WIDTH, MAX_RENDER_HEIGHT
    root.visual.quality.offsamples = 0
    root.visual.headlight.ambient = list(HEADLIGHT_AMBIENT)
    root.visual.headlight.diffuse = list(HEADLIGHT_DIFFUSE)
    root.visual.headlight.specular = [0.0, 0.0, 0.0]
    root.worldbody.add(
        "geom",
        name=FLOOR_NAME,
        type="plane",
        size=[FLOOR_HALF_SIZE, FLOOR_HALF_SIZE, 0.05],
        rgba=list(FLOOR_RGBA),
        group=2,
    )
    return root


def _add_table(root: mjcf.RootElement, table: TableSpec, models_dir: Path) -> None:
    """models/table.xml under the table's centre; a visual top if the model's top is hidden."""
    tx, ty = table.position_xy
    root.attach(_load(models_dir / TABLE_XML, TABLE_MODEL)).pos = [tx, ty, 0.0]
    if _has_visible_top(models_dir / TABLE_XML, table.height):
        return
    sx, sy = table.size_xy
    root.worldbody.add(
        "geom",
        name=TABLE_VISUAL_NAME,
        type="box",
        contype=0,
        conaffinity=0,
        group=2,
        size=[0.5 * sx, 0.5 * sy, 0.5 * TABLE_VISUAL_THICKNESS],
        pos=[tx, ty, table.height - 0.5 * TABLE_VISUAL_THICKNESS],
        rgba=list(TABLE_VISUAL_RGBA),
    )


def _add_light_and_camera(root: mjcf.RootElement, table: TableSpec) -> None:
    """A shadowless directional light from above and the downward-looking overhead camera."""
    tx, ty = table.position_xy
    root.worldbody.add(
        "light",
        name="overhead_light",
        pos=[tx, ty, table.height + 2.0],
        dir=[0, 0, -1],
        directional=True,
        castshadow=False,
        diffuse=list(LIGHT_DIFFUSE),
    )
    root.worldbody.add(
        "camera",
        name=CAMERA_NAME,
        pos=[tx, ty, table.height + camera_height_above_table(table.size_xy)],
        quat=[1.0, 0.0, 0.0, 0.0],  # MuJoCo cameras look along their -z: straight down
        fovy=CAMERA_FOVY_DEG,
    )


def _add_robot(root: mjcf.RootElement, models_dir: Path, kind: str) -> dict[str, float]:
    """The arm at its base position with the ``kind`` hand on its flange; returns the home
    posture."""
    arm = _load(models_dir / ARM_XML, robot.ARM_MODEL)
    hand = _load(models_dir / HAND_XMLS[kind], robot.HAND_MODEL)
    if kind == "tendon":
        _add_target_registers(hand)
        root.option.actuatorgroupdisable = [TARGET_REGISTER_GROUP]
    site = arm.find("site", robot.ATTACHMENT_SITE)
    if site is None:
        raise SimulationError(f"{models_dir / ARM_XML}: no site {robot.ATTACHMENT_SITE!r}")
    site.attach(hand)
    frame = root.attach(arm)
    frame.pos = list(ARM_BASE_POSITION)
    frame.quat = [math.cos(ARM_BASE_YAW / 2), 0.0, 0.0, math.sin(ARM_BASE_YAW / 2)]
    return _home_posture(models_dir / ARM_XML)


def _add_target_registers(hand: mjcf.RootElement) -> None:
    """Give the tendon hand the 16 joint-target registers the servo hand's position actuators
    are: position actuators with its names (:data:`robot.HAND_ACTUATORS`), the joint ranges as
    control ranges and the PD stiffness (:data:`~hand_sim.tendon_drive.SERVO_KP`) as gain, in
    the actuator group :data:`TARGET_REGISTER_GROUP` that the world disables. They exert no
    force: their ``ctrl`` holds the joint targets that :class:`~hand_sim.tendon_drive.TendonDrive`
    turns into tensions at every step, and code that reads the servo hand's targets, ranges or
    stiffness by name (``RobotIndices.hand_ctrl``) reads the tendon hand's the same way."""
    for name, joint in zip(robot.HAND_ACTUATORS, robot.HAND_JOINTS, strict=True):
        hand.actuator.add(
            "position",
            name=name,
            joint=joint,
            kp=SERVO_KP[int(joint[-1])],
            inheritrange=1,
            group=TARGET_REGISTER_GROUP,
        )


def _home_posture(path: Path) -> dict[str, float]:
    """Joint values of the ``home`` keyframe of the standalone arm model, by joint name."""
    model = mujoco.MjModel.from_xml_path(str(path))
    try:
        key = model.key(robot.HOME_KEYFRAME)
    except KeyError as e:
        raise SimulationError(f"{path}: no keyframe {robot.HOME_KEYFRAME!r}") from e
    out = {}
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            out[model.joint(j).name] = float(key.qpos[model.jnt_qposadr[j]])
    return out


def _load(path: Path, model_name: str) -> mjcf.RootElement:
    """Parse an MJCF file as an attachable model called ``model_name``, without its keyframes
    (dm_control cannot merge keyframes of attached models)."""
    if not path.is_file():
        raise SimulationError(f"model file {path} not found")
    try:
        element = mjcf.from_path(str(path))
    except Exception as e:  # dm_control raises several kinds of parse errors
        raise SimulationError(f"{path}: cannot be parsed: {e}") from e
    element.model = model_name
    for key in list(element.keyframe.all_children()) if element.keyframe else []:
        key.remove()
    return element


def _has_visible_top(path: Path, height: float) -> bool:
    """Does the standalone table model have a geom in a rendered group (0-2) at its top?"""
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return any(
        model.geom_group[g] <= 2
        and model.geom_rgba[g, 3] > 0
        and abs(geom_top(model, data, g) - height) <= TABLE_HEIGHT_TOLERANCE
        for g in range(model.ngeom)
    )


def geom_top(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> float:
    """Highest world z of a geom's bounding box (exact for boxes in any orientation)."""
    centre, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
    R = data.geom_xmat[geom].reshape(3, 3)
    return float(data.geom_xpos[geom, 2] + R[2] @ centre + np.abs(R[2]) @ half)
