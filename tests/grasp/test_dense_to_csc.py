"""The linear programs' constraint matrices (controllers.grasp.score.dense_to_csc) are exactly
what scipy's own conversion makes: the same nonzeros, row indices and column pointers, exact
zeros (of either sign) left out, so clarabel is given the same problem."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from controllers.grasp.score import dense_to_csc


def test_dense_to_csc_is_scipys_conversion() -> None:
    rng = np.random.default_rng(3)
    for shape in [(3, 6), (19, 12), (1, 1), (5, 2)]:
        m = rng.normal(size=shape)
        m[rng.random(shape) < 0.5] = 0.0
        m[rng.random(shape) < 0.1] = -0.0
        ours, theirs = dense_to_csc(m), sp.csc_matrix(m)
        assert ours.shape == theirs.shape
        np.testing.assert_array_equal(ours.data, theirs.data)
        np.testing.assert_array_equal(ours.indices, theirs.indices)
        np.testing.assert_array_equal(ours.indptr, theirs.indptr)
        np.testing.assert_array_equal(ours.toarray(), m)
    empty = dense_to_csc(np.zeros((4, 4)))
    assert empty.nnz == 0 and empty.indptr.tolist() == [0] * 5
