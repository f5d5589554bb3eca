"""The world as the robot believes it: a private MuJoCo model in which the block to pick is the
prism that vision perceived, not the simulated one (section 5.2: "the Hough edge detection
algorithm is then used to extract a 2D object contour model, which is extruded in the z direction").

The planners (coarse reach, posture control) check collisions in a model like this one. The
simulated target block is kept (its free joint keeps the model's state layout) but made a ghost
that collides with nothing; a static prism built from the perceived polygon, centroid, yaw and
height takes its place. Every other element, and every element's index, is the world's.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.errors import ReachError
from controllers.grasp.polygon import Polygon
from hand_sim.blocks import GEOM_SUFFIX, prism_faces
from hand_sim.world import World

#: Names of the perceived prism's body, mesh and geom in the planning model.
PERCEIVED_BODY = "perceived_target"
PERCEIVED_MESH = PERCEIVED_BODY + "_mesh"
PERCEIVED_GEOM = PERCEIVED_BODY + "_geom"


def perceived_prism_vertices(
    polygon: Polygon, yaw: float, position_xy: tuple[float, float], bottom: float, top: float
) -> NDArray[np.float64]:
    """(2k, 3) world vertices of ``polygon`` (object frame) turned by ``yaw``, centred at
    ``position_xy`` and extruded from z = ``bottom`` to z = ``top``: bottom face, then top."""
    c, s = np.cos(yaw), np.sin(yaw)
    xy = polygon.vertices @ np.array([[c, s], [-s, c]]) + np.asarray(position_xy, dtype=float)
    k = len(xy)
    return np.vstack(
        [np.column_stack([xy, np.full(k, bottom)]), np.column_stack([xy, np.full(k, top)])]
    )


def planning_model(
    world: World,
    target_name: str,
    polygon: Polygon,
    yaw: float,
    position_xy: tuple[float, float],
    top_z: float,
) -> mujoco.MjModel:
    """A compiled copy of ``world``'s model in which block ``target_name`` is the perceived prism
    (``polygon`` in its object frame, turned by ``yaw`` about z, centroid at ``position_xy``,
    standing on the table up to ``top_z``). Element indices and the state layout are the world's
    (the perceived prism is appended as a static body)."""
    world.block_body_id(target_name)  # raises SceneError listing the blocks
    bottom = world.scene.table.height
    if not top_z > bottom:
        raise ReachError(f"perceived top z = {top_z} m is not above the table ({bottom} m)")
    root = world.mjcf_root
    spec = mujoco.MjSpec.from_string(root.to_xml_string(), root.get_assets())
    verts = perceived_prism_vertices(polygon, yaw, position_xy, bottom, top_z)
    spec.add_mesh(
        name=PERCEIVED_MESH,
        uservert=verts.ravel().tolist(),
        userface=prism_faces(polygon.n_edges).ravel().tolist(),
    )
    body = spec.worldbody.add_body(name=PERCEIVED_BODY)
    true_geom = spec.geom(target_name + GEOM_SUFFIX)
    body.add_geom(
        name=PERCEIVED_GEOM,
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=PERCEIVED_MESH,
        contype=true_geom.contype,
        conaffinity=true_geom.conaffinity,
        group=3,
    )
    true_geom.contype = 0
    true_geom.conaffinity = 0
    try:
        return spec.compile()
    except ValueError as e:
        raise ReachError(f"the perceived block does not make a valid model: {e}") from e
