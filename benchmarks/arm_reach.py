"""Does the arm of models/arm.xml, carrying models/hand.xml, reach the whole table top?

For a grid of block positions over the table top (world layout of hand_sim: table centred at the
origin, arm base ``ARM_BASE_X`` m along -x), solve the arm's inverse kinematics in closed form for

  * a top grasp: tool axis straight down, palm face ``TOP_CLEARANCE`` above the top of a 20 cm
    block, any wrist roll (the roll sets the grasp yaw);
  * a lateral grasp: tool axis horizontal along the radial line from the waist axis (reaching
    out, or reaching past the block and pointing back at the base for blocks close to it), palm
    face ``LATERAL_CLEARANCE`` from a 5 cm block's side at ``LATERAL_HEIGHT`` above the table;

inside the joint limits and with no arm or hand geom touching the table or each other (hand in a
pre-grasp posture, ``PREGRASP``). Prints the share of grid points reached per grasp kind and the
ones that are not. Usage: ``.venv/bin/python -m benchmarks.arm_reach [--step 0.05]``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim import clitools as cli
from hand_sim.resources import models_dir

MODELS = models_dir()
ARM_JOINTS = ("waist", "shoulder", "elbow", "wrist_pitch", "wrist_roll")
FINGERS = ("ff", "mf", "rf", "th")

#: World layout (hand_sim.assembly / hand_sim.scene): table centre, size, top height; arm base.
TABLE_CENTRE = np.array([0.0, 0.0])
TABLE_SIZE = np.array([0.9, 0.9])
TABLE_TOP = 0.75
ARM_BASE_X = -0.60
#: Block centroids stay this far inside the table edge (half a 5 cm block plus the scene margin).
EDGE_MARGIN = 0.03
BLOCK_HEIGHT = 0.20
BLOCK_RADIUS = 0.03
#: Arm kinematics (models/arm.xml): shoulder height, upper arm, forearm, wrist pitch axis to flange.
SHOULDER_Z = 1.00
UPPER_ARM = 0.60
FOREARM = 0.56
WRIST_TO_FLANGE = 0.08
#: Hand (models/hand.xml): palm face to mount along the tool axis.
PALM_THICKNESS = 0.025
TOP_CLEARANCE = 0.02
LATERAL_CLEARANCE = 0.015
LATERAL_HEIGHT = 0.12
#: Hand joints in the pre-grasp posture: MCPs at 1.2 rad, the rest straight.
PREGRASP = np.tile([0.0, 1.2, 0.3, 0.2], 4)


def build() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Arm at the origin, hand attached (prefix ``arm/hand/``), the table at its place."""
    world = mujoco.MjSpec()
    world.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    world.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    world.option.impratio = 10.0
    arm = mujoco.MjSpec.from_file(str(MODELS / "arm.xml"))
    hand = mujoco.MjSpec.from_file(str(MODELS / "hand.xml"))
    table = mujoco.MjSpec.from_file(str(MODELS / "table.xml"))
    arm.attach(hand, site=arm.site("attachment_site"), prefix="hand/")
    world.worldbody.add_frame().attach_body(arm.body("arm_base"), "arm/", "")
    frame = world.worldbody.add_frame(pos=[TABLE_CENTRE[0] - ARM_BASE_X, TABLE_CENTRE[1], 0.0])
    frame.attach_body(table.body("table"), "table/", "")
    model = world.compile()
    return model, mujoco.MjData(model)


def planar_ik(r: float, h: float, pitch_sum: float) -> list[NDArray[np.float64]]:
    """(shoulder, elbow, wrist_pitch) putting the wrist pitch axis at radial distance ``r`` and
    height ``h`` above the shoulder with shoulder + elbow + wrist_pitch = ``pitch_sum``; both
    elbow branches, empty when out of reach. Angles from the vertical, positive towards +r."""
    d2 = r * r + h * h
    c2 = (d2 - UPPER_ARM**2 - FOREARM**2) / (2.0 * UPPER_ARM * FOREARM)
    if abs(c2) > 1.0:
        return []
    out = []
    for elbow in (np.arccos(c2), -np.arccos(c2)):
        shoulder = np.arctan2(r, h) - np.arctan2(
            FOREARM * np.sin(elbow), UPPER_ARM + FOREARM * np.cos(elbow)
        )
        out.append(np.array([shoulder, elbow, pitch_sum - shoulder - elbow]))
    return out


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def candidates(kind: str, xy_arm: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """Arm joint vectors (5,) for a grasp of a block at ``xy_arm`` (arm frame)."""
    waist = float(np.arctan2(xy_arm[1], xy_arm[0]))
    r = float(np.hypot(*xy_arm))
    out = []
    if kind == "top":
        h = TABLE_TOP + BLOCK_HEIGHT + TOP_CLEARANCE + PALM_THICKNESS + WRIST_TO_FLANGE - SHOULDER_Z
        poses = [(r, h, np.pi)]
    else:
        back = BLOCK_RADIUS + LATERAL_CLEARANCE + PALM_THICKNESS + WRIST_TO_FLANGE
        h = TABLE_TOP + LATERAL_HEIGHT - SHOULDER_Z
        poses = [(r - back, h, 0.5 * np.pi), (r + back, h, -0.5 * np.pi)]
    for rr, hh, pitch in poses:
        for sew in planar_ik(rr, hh, pitch):
            for roll in (0.0, 0.5 * np.pi):
                out.append(np.array([waist, *_wrap(sew), roll]))
    return out


def feasible(model: mujoco.MjModel, data: mujoco.MjData, q: NDArray[np.float64]) -> bool:
    """Inside the joint limits, no robot geom touching the table or another robot geom."""
    joints = [model.joint("arm/" + j) for j in ARM_JOINTS]
    for j, v in zip(joints, q, strict=True):
        if not j.range[0] <= v <= j.range[1]:
            return False
    data.qpos[:] = 0.0
    for j, v in zip(joints, q, strict=True):
        data.qpos[j.qposadr[0]] = v
    for k, f in enumerate(FINGERS):
        for i in range(4):
            data.qpos[model.joint(f"arm/hand/{f}j{i}").qposadr[0]] = PREGRASP[4 * k + i]
    mujoco.mj_forward(model, data)
    return not any(c.dist < 0.0 for c in data.contact[: data.ncon])


def grid(step: float) -> NDArray[np.float64]:
    """Block positions (world x, y) covering the table top inside EDGE_MARGIN."""
    lo = TABLE_CENTRE - 0.5 * TABLE_SIZE + EDGE_MARGIN
    hi = TABLE_CENTRE + 0.5 * TABLE_SIZE - EDGE_MARGIN
    xs = np.linspace(lo[0], hi[0], int(np.ceil((hi[0] - lo[0]) / step)) + 1)
    ys = np.linspace(lo[1], hi[1], int(np.ceil((hi[1] - lo[1]) / step)) + 1)
    return np.array([(x, y) for x in xs for y in ys])


def coverage(step: float) -> dict[str, NDArray[np.bool_]]:
    model, data = build()
    points = grid(step)
    result = {}
    for kind in ("top", "lateral"):
        ok = np.zeros(len(points), dtype=bool)
        for k, xy in enumerate(points):
            xy_arm = xy - np.array([ARM_BASE_X, 0.0])
            ok[k] = any(feasible(model, data, q) for q in candidates(kind, xy_arm))
        result[kind] = ok
    return result


PROG = "python -m benchmarks.arm_reach"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=cli.ERRORS)


def _run(argv: Sequence[str] | None) -> int:
    ap = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    ap.add_argument(
        "--step", type=cli.number(0.01, 0.45), default=0.05, help="grid spacing, m, 0.01..0.45"
    )
    args = ap.parse_args(argv)
    points = grid(args.step)
    result = coverage(args.step)
    size, centre = TABLE_SIZE.tolist(), TABLE_CENTRE.tolist()
    print(
        f"# table {size} m centred at {centre}, top at {TABLE_TOP} m; arm base at ({ARM_BASE_X}, 0)"
    )
    print(f"# {len(points)} block positions on a {args.step} m grid")
    for kind, ok in result.items():
        print(f"{kind:8s} reached {ok.mean() * 100:5.1f} % ({ok.sum()}/{ok.size})")
        for xy in points[~ok]:
            print(f"    not reached: ({xy[0]:+.3f}, {xy[1]:+.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
