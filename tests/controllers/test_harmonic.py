"""Tests of the n-D harmonic-function planner (controllers.planning.harmonic)."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from controllers.errors import GridError
from controllers.planning.harmonic import GridSpec, ascend, solve_harmonic


def bfs_distance(free: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Face-connected BFS distance (in cells) from the goal set; -1 where unreachable."""
    dist = np.full(free.shape, -1, dtype=int)
    queue = deque()
    for cell in zip(*np.nonzero(goal & free), strict=True):
        dist[cell] = 0
        queue.append(cell)
    while queue:
        cell = queue.popleft()
        for axis in range(free.ndim):
            for sign in (-1, 1):
                nb = list(cell)
                nb[axis] += sign
                nb = tuple(nb)
                if 0 <= nb[axis] < free.shape[axis] and free[nb] and dist[nb] < 0:
                    dist[nb] = dist[cell] + 1
                    queue.append(nb)
    return dist


def perfect_maze(rng: np.random.Generator, cells: int) -> np.ndarray:
    """A perfect maze (one path between any two cells) by randomized depth-first search on a
    ``cells x cells`` lattice, drawn on a ``(2*cells+1)^2`` grid of one-cell-wide corridors."""
    size = 2 * cells + 1
    free = np.zeros((size, size), dtype=bool)
    seen = np.zeros((cells, cells), dtype=bool)
    stack = [(0, 0)]
    seen[0, 0] = True
    free[1, 1] = True
    while stack:
        r, c = stack[-1]
        options = [
            (r + dr, c + dc)
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= r + dr < cells and 0 <= c + dc < cells and not seen[r + dr, c + dc]
        ]
        if not options:
            stack.pop()
            continue
        nr, nc = options[rng.integers(len(options))]
        seen[nr, nc] = True
        free[2 * nr + 1, 2 * nc + 1] = True
        free[r + nr + 1, c + nc + 1] = True
        stack.append((nr, nc))
    return free


def path_cells(path) -> list[tuple[int, ...]]:
    return [tuple(int(v) for v in np.rint(p)) for p in path.points]


def test_random_obstacles_reachability_matches_bfs():
    rng = np.random.default_rng(0)
    for _ in range(5):
        free = rng.random((30, 30)) > 0.35
        goal = np.zeros_like(free)
        goal[15, 15] = free[15, 15] = True
        field = solve_harmonic(free, goal)
        dist = bfs_distance(free, goal)
        np.testing.assert_array_equal(np.isfinite(field.log_phi), dist >= 0)
        starts = np.argwhere(dist > 0)
        for start in starts[rng.choice(len(starts), size=min(15, len(starts)), replace=False)]:
            path = ascend(field, start)
            assert path.found, path.reason
            cells = path_cells(path)
            assert goal[cells[-1]]
            assert all(free[c] for c in cells)


def test_perfect_maze_every_cell_reaches_the_goal_along_the_unique_corridor():
    rng = np.random.default_rng(1)
    free = perfect_maze(rng, 12)
    goal = np.zeros_like(free)
    goal[1, 1] = True
    field = solve_harmonic(free, goal)
    dist = bfs_distance(free, goal)
    assert dist.max() > 60  # long corridors: u = 1 - phi is flat in float64 there
    far = tuple(np.argwhere(dist == dist.max())[0])
    assert field.u[far] == 1.0
    assert field.n_levels > 1
    for start in np.argwhere(dist > 0)[::7]:
        path = ascend(field, start)
        assert path.found, (tuple(start), path.reason)
        cells = path_cells(path)
        assert all(free[c] for c in cells)
        # in a perfect maze the only route follows the BFS distance down by one per cell
        visited = [c for i, c in enumerate(cells) if i == 0 or c != cells[i - 1]]
        d = [dist[c] for c in visited]
        assert d == list(range(dist[tuple(start)], -1, -1))


def test_no_local_maxima_every_reachable_cell_has_a_higher_neighbour():
    rng = np.random.default_rng(2)
    free = rng.random((25, 25, 6)) > 0.3
    goal = np.zeros_like(free)
    goal[3, 3, 3] = free[3, 3, 3] = True
    field = solve_harmonic(free, goal)
    lp = np.pad(field.log_phi, 1, constant_values=-np.inf)
    best = np.full(field.shape, -np.inf)
    for axis in range(3):
        for sign in (-1, 1):
            shifted = np.roll(lp, sign, axis=axis)[1:-1, 1:-1, 1:-1]
            best = np.maximum(best, shifted)
    inner = np.isfinite(field.log_phi) & ~field.goal
    assert np.all(best[inner] > field.log_phi[inner])


def test_potential_solves_laplace_against_a_direct_solve():
    rng = np.random.default_rng(3)
    free = rng.random((14, 11)) > 0.25
    goal = np.zeros_like(free)
    goal[2, 9] = free[2, 9] = True
    field = solve_harmonic(free, goal)
    reach = bfs_distance(free, goal) > 0
    idx = np.flatnonzero(reach)
    pos = {p: i for i, p in enumerate(idx)}
    A = sp.lil_matrix((len(idx), len(idx)))
    b = np.zeros(len(idx))
    for p, i in pos.items():
        r, c = np.unravel_index(p, free.shape)
        A[i, i] = 4.0
        for rr, cc in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if 0 <= rr < free.shape[0] and 0 <= cc < free.shape[1]:
                q = np.ravel_multi_index((rr, cc), free.shape)
                if q in pos:
                    A[i, pos[q]] = -1.0
                elif goal[rr, cc]:
                    b[i] += 1.0
    phi = spla.spsolve(A.tocsc(), b)
    np.testing.assert_allclose(np.exp(field.log_phi.ravel()[idx]), phi, rtol=1e-8)


def test_long_corridor_matches_closed_form_and_the_gradient_still_leads_home():
    # One-cell-wide corridor: 4 v_i = v_{i-1} + v_{i+1}, v = 1 at the goal, 0 past the dead end.
    n = 400
    free = np.zeros((3, n + 2), dtype=bool)
    free[1, 1 : n + 1] = True
    goal = np.zeros_like(free)
    goal[1, 1] = True
    field = solve_harmonic(free, goal)
    mu = np.arccosh(2.0)
    i = np.arange(n)
    exact = np.log(np.sinh((n - i) * mu)) - np.log(np.sinh(n * mu))
    np.testing.assert_allclose(field.log_phi[1, 1 : n + 1], exact, rtol=1e-10, atol=1e-10)
    assert exact[-1] < -500  # phi ~ 1e-228: u is exactly 1.0 over most of the corridor
    assert np.count_nonzero(field.u[1, 1 : n + 1] == 1.0) > n - 40
    path = ascend(field, [1.0, float(n)])
    assert path.found
    assert path_cells(path)[-1] == (1, 1)


def test_no_path_when_a_wall_separates_start_and_goal():
    free = np.ones((20, 20), dtype=bool)
    free[:, 10] = False
    goal = np.zeros_like(free)
    goal[5, 15] = True
    field = solve_harmonic(free, goal)
    assert not field.reachable((5, 3))
    path = ascend(field, [5.0, 3.0])
    assert not path.found
    assert "no path" in path.reason
    blocked = ascend(field, [5.0, 10.0])
    assert not blocked.found
    assert "obstacle" in blocked.reason
    free[12, 10] = True  # open a door: now there is a path, and it goes through the door
    field = solve_harmonic(free, goal)
    path = ascend(field, [5.0, 3.0])
    assert path.found
    assert (12, 10) in path_cells(path)


def test_no_goal_cells_reports_no_path():
    free = np.ones((6, 6), dtype=bool)
    goal = np.zeros_like(free)
    goal[2, 2] = True
    free[2, 2] = False  # goal inside an obstacle is ignored
    field = solve_harmonic(free, goal)
    path = ascend(field, [0.0, 0.0])
    assert not path.found


def test_four_dimensional_wall_with_a_hole():
    n = 12
    free = np.ones((n,) * 4, dtype=bool)
    free[6] = False
    free[6, 9, 9, 2] = True  # the only hole in the wall at x0 = 6
    goal = np.zeros_like(free)
    goal[10, 2, 2, 9] = True
    field = solve_harmonic(free, goal)
    dist = bfs_distance(free, goal)
    np.testing.assert_array_equal(np.isfinite(field.log_phi), dist >= 0)
    path = ascend(field, [1.0, 1.0, 1.0, 1.0])
    assert path.found, path.reason
    cells = path_cells(path)
    assert (6, 9, 9, 2) in cells
    assert all(free[c] for c in cells)
    # the path is no more than ~1.5x the shortest (Manhattan, through the hole) route
    assert path.length < 1.5 * dist[1, 1, 1, 1]


def test_gridspec_round_trip_and_validation():
    spec = GridSpec((-1.0, 0.0), (1.0, 2.0), (5, 9))
    q = np.array([0.3, 1.7])
    np.testing.assert_allclose(spec.to_config(spec.to_grid(q)), q)
    assert spec.nearest_cell([-1.0, 2.0]) == (0, 8)
    assert spec.node_configs().shape == (45, 2)
    np.testing.assert_allclose(spec.node_configs()[-1], [1.0, 2.0])
    with pytest.raises(GridError, match="lower"):
        GridSpec((1.0,), (0.0,), (3,))
    with pytest.raises(GridError, match="shape"):
        GridSpec((0.0,), (1.0,), (1,))
    with pytest.raises(GridError, match="differ"):
        solve_harmonic(np.ones((3, 3)), np.ones((3, 4)))
    with pytest.raises(GridError, match="outside"):
        ascend(solve_harmonic(np.ones((3, 3)), np.eye(3)), [5.0, 0.0])
