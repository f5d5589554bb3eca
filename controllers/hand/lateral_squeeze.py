"""How hard each finger of a lateral grasp presses (section 5.2, Grasp Object's squeeze), with
the 3-D contact model of section 3.5: the fingers press from different heights (the middle
finger high, the thumb low) on faces that need not oppose one another.

The total squeeze is that of the shares balancing the contacts by least squares near the planar
S_G programme's normal forces (Eq. 13; :func:`controllers.hand.grip.balanced_shares`), its strongest
finger at GRIP_FORCE. That total is shared out as the normal forces that hold the block's weight
at its centre with the most friction to spare (:func:`controllers.grasp.holding.holding_forces`),
whose reserve also rates the grasp: a negative one means the contacts cannot hold the block by
the model, whatever the squeeze."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.holding import holding_forces
from controllers.hand.grip import GRIP_FORCE, MIN_SHARE, balanced_shares


@dataclass(frozen=True)
class LateralSqueeze:
    """A lateral squeeze: each pressing finger's normal force (N) and the contacts' friction
    reserve (N) by the 3-D model (None where no forces within the bounds hold the weight)."""

    forces: NDArray[np.float64]
    reserve: float | None

    @property
    def grip_force(self) -> float:
        """The mean normal force (N)."""
        return float(self.forces.mean())


def lateral_squeeze(
    points: ArrayLike,
    normals: ArrayLike,
    planar: ArrayLike,
    weight: float,
    centre: ArrayLike,
    *,
    holding: bool = True,
) -> LateralSqueeze:
    """The squeeze of pressing contacts at world ``points`` (n, 3) with outward ``normals``
    (n, 3), the planar S_G programme's normal forces ``planar`` (n,) as the balance's prior, for
    a block of ``weight`` (N) whose centre of mass is ``centre`` (3,). ``holding``: share the
    total out by :func:`controllers.grasp.holding.holding_forces` (else the balanced shares
    themselves; the reserve is computed either way)."""
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    shares = balanced_shares(p, n, planar)
    balanced = GRIP_FORCE * shares / shares.max()
    mean = float(balanced.mean())
    hold = holding_forces(
        p,
        n,
        centre,
        weight,
        total=mean * len(p),
        max_force=GRIP_FORCE,
        min_force=min(MIN_SHARE * GRIP_FORCE, mean),
    )
    if not hold.solved:
        return LateralSqueeze(balanced, None)
    return LateralSqueeze(hold.normal_forces if holding else balanced, hold.reserve)
