"""A lateral grasp's squeeze (controllers.hand.lateral_squeeze): as hard in all as the balanced
shares with their strongest finger at GRIP_FORCE, shared out to hold the weight, and its reserve
against the hand-derived one of a thumb pressing below two fingers."""

import numpy as np
import pytest

from controllers.hand.grip import GRIP_FORCE, balanced_shares
from controllers.hand.lateral_squeeze import lateral_squeeze

# two fingers on one face (x = +2 cm, y = +-1.5 cm), the thumb on the opposite face, the block's
# centre at the origin
NORMALS = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
PLANAR = np.array([1.0, 1.0, 2.0])


def points(thumb_z: float, finger_z: float = 0.05) -> np.ndarray:
    return np.array([[0.02, 0.015, finger_z], [0.02, -0.015, finger_z], [-0.02, 0.0, thumb_z]])


def test_the_squeeze_keeps_the_balanced_total_and_no_finger_exceeds_the_grip_force() -> None:
    # an equilateral triangle's three faces (normals 120 deg apart), the thumb at three heights
    normals = np.array([[0.5, 0.866025, 0.0], [0.5, -0.866025, 0.0], [-1.0, 0.0, 0.0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for thumb_z in (0.05, -0.03, -0.07):
        p = 0.015 * normals + np.array([0.0, 0.0, 1.0]) * [[0.05], [0.04], [thumb_z]]
        shares = balanced_shares(p, normals, PLANAR)
        balanced = GRIP_FORCE * shares / shares.max()
        held = lateral_squeeze(p, normals, PLANAR, 1.5, np.zeros(3))
        plain = lateral_squeeze(p, normals, PLANAR, 1.5, np.zeros(3), holding=False)
        assert held.reserve is not None
        assert held.forces.sum() == pytest.approx(balanced.sum(), rel=1e-6)
        assert held.forces.max() <= GRIP_FORCE + 1e-6
        np.testing.assert_allclose(plain.forces, balanced)
        assert plain.reserve == pytest.approx(held.reserve)  # the contacts' rating either way


def test_the_reserve_of_opposed_contacts_at_one_height_is_hand_derived() -> None:
    # level: the balance gives the thumb as much as the two fingers together; the total T is
    # shared thumb T / 2, fingers T / 4 each, and each side carries half the 1.5 N weight by
    # friction: the fingers keep T / 4 - 0.375 N (mu = 1), the least
    p = points(0.05)
    squeeze = lateral_squeeze(p, NORMALS, PLANAR, 1.5, np.zeros(3))
    total = squeeze.forces.sum()
    np.testing.assert_allclose(squeeze.forces, [total / 4, total / 4, total / 2], atol=1e-5)
    assert squeeze.reserve == pytest.approx(total / 4 - 0.375, abs=1e-5)


def test_a_thumb_below_two_opposed_fingers_keeps_the_balanced_squeeze_without_a_reserve() -> None:
    # with the thumb low, the least-squares balance presses the fingers harder than the thumb
    # (4.9 + 4.9 N against 6 N) to lessen the moment; their normals all lie along x, whose
    # tangents carry no force along x, so no shares of that total balance the block: the
    # balanced squeeze stays, and the grasp has no reserve
    for thumb_z in (-0.03, -0.07):
        p = points(thumb_z)
        shares = balanced_shares(p, NORMALS, PLANAR)
        squeeze = lateral_squeeze(p, NORMALS, PLANAR, 1.5, np.zeros(3))
        assert squeeze.reserve is None
        np.testing.assert_allclose(squeeze.forces, GRIP_FORCE * shares / shares.max())
        assert squeeze.forces[:2].sum() > squeeze.forces[2] + 1.0
