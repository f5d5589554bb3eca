"""Prism blocks as MJCF: a polygon footprint extruded into a free-floating wooden prism.

Section 5.1 of the paper: "wood blocks ... approximately 20 cm in height, and with maximum distance
between edges of 5 cm ... prisms with polygonal bases ranging from triangles to hexagons". The
collision geometry is a convex MuJoCo mesh built from the footprint's vertices at the bottom and
top faces; mass and inertia follow from the mesh volume and the density of wood.
"""

from __future__ import annotations

import numpy as np
from dm_control import mjcf
from numpy.typing import NDArray

from controllers.grasp import Polygon
from hand_sim.scene_spec import BlockSpec

#: Density of a hardwood such as maple or beech (kg/m^3).
WOOD_DENSITY = 700.0
#: Friction of the block's surface (sliding, torsional m, rolling m). MuJoCo combines the two geoms
#: of a contact by taking the larger coefficient, so the table (models/table.xml) carries the same
#: 0.45, a dry wood-on-lacquered-wood value (docs/models.md); the fingertip pads take precedence
#: (``priority``) with their own 1.0.
BLOCK_FRICTION = (0.45, 0.005, 0.0001)
#: Suffixes of the MJCF elements made for block ``name``.
MESH_SUFFIX, GEOM_SUFFIX, JOINT_SUFFIX = "_mesh", "_geom", "_free"


def prism_vertices(polygon: Polygon, height: float) -> NDArray[np.float64]:
    """The (2k, 3) vertices of ``polygon`` extruded symmetrically about z = 0 to ``height`` m:
    the bottom face's k vertices at z = -height/2, then the top face's at +height/2."""
    v = polygon.vertices
    k = len(v)
    bottom = np.column_stack([v, np.full(k, -0.5 * height)])
    top = np.column_stack([v, np.full(k, 0.5 * height)])
    return np.vstack([bottom, top])


def prism_faces(n_sides: int) -> NDArray[np.int64]:
    """Triangles (CCW seen from outside) of a prism with ``n_sides`` side faces, indexing
    :func:`prism_vertices`' layout: fans on the bottom and top faces and two per side."""
    k = n_sides
    tris = []
    for i in range(1, k - 1):
        tris.append((0, i + 1, i))  # bottom, facing -z
        tris.append((k, k + i, k + i + 1))  # top, facing +z
    for i in range(k):
        j = (i + 1) % k
        tris.append((i, j, k + j))
        tris.append((i, k + j, k + i))
    return np.array(tris, dtype=np.int64)


def block_quaternion(yaw: float) -> NDArray[np.float64]:
    """Unit quaternion (w, x, y, z) of a rotation by ``yaw`` rad about z."""
    return np.array([np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)])


def add_block(root: mjcf.RootElement, block: BlockSpec, table_top: float) -> mjcf.Element:
    """Add ``block`` to ``root`` as a free body resting on the plane z = ``table_top``.

    Creates the mesh asset ``<name>_mesh``, the body ``<name>`` (its frame at the prism's centroid,
    mid-height), the free joint ``<name>_free`` and the geom ``<name>_geom``. Returns the body.
    """
    verts = prism_vertices(block.polygon, block.height)
    mesh = root.asset.add(
        "mesh",
        name=block.name + MESH_SUFFIX,
        vertex=verts.ravel(),
        face=prism_faces(block.polygon.n_edges).ravel(),
    )
    x, y = block.position
    body = root.worldbody.add(
        "body",
        name=block.name,
        pos=[x, y, table_top + 0.5 * block.height],
        quat=block_quaternion(block.yaw),
    )
    body.add("freejoint", name=block.name + JOINT_SUFFIX)
    body.add(
        "geom",
        name=block.name + GEOM_SUFFIX,
        type="mesh",
        mesh=mesh,
        density=WOOD_DENSITY,
        rgba=list(block.rgba),
        friction=list(BLOCK_FRICTION),
        condim=3,
        group=0,
    )
    return body
