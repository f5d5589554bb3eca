"""Harmonic-function path planning on an n-dimensional grid (Connolly & Grupen, "The applications
of harmonic functions to robotics", 1993; used for coarse reach and delivery in section 5.2).

Obstacle cells and the space outside the grid are held at potential ``u = 1``, goal cells at
``u = 0``, and Laplace's equation is solved on the free cells. A harmonic function has no local
minima, so following ``-grad u`` from any free cell connected to a goal reaches the goal.

Flat potentials. Far from the goal, ``1 - u`` falls off exponentially (by ~0.27 per cell along a
one-cell-wide 2-D corridor), so ``u`` rounds to exactly 1 in float64 after a few dozen cells and
its gradient vanishes. We therefore solve for ``phi = 1 - u`` (goal 1, obstacles 0), whose small
values float64 represents with full relative precision, and keep ``log(phi)``. Conjugate gradients
give ``phi`` to an absolute accuracy near 1e-15, so cells where ``phi`` falls below
``RESCALE_THRESHOLD`` are solved again as their own Dirichlet problem, with the already accurate
neighbours (rescaled to order 1) as boundary data: the same harmonic function, computed piecewise
with fresh precision (an exact alternative to the log-space iteration of Wray et al., IROS 2016).
Paths ascend ``log(phi)`` of the multilinear interpolation, which is scale-free.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.ndimage as ndi
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from controllers.errors import GridError

#: Cells whose ``phi`` (relative to the boundary data of their solve) falls below this are solved
#: again in a rescaled sub-problem; CG's absolute error (~1e-15) stays ~1e-9 of such values.
RESCALE_THRESHOLD = 1e-6
#: Relative residual at which conjugate gradients stop.
CG_RTOL = 1e-13
#: Upper bound on CG iterations per solve, as a multiple of the grid's largest side.
CG_MAXITER_PER_SIDE = 200
#: Default gradient-ascent step, in cells.
DEFAULT_STEP = 0.25
#: Steps allowed per cell of the grid's summed side lengths before a path is declared stalled.
STEPS_PER_CELL = 16


@dataclass(frozen=True)
class GridSpec:
    """A regular grid over a box of configuration space; node ``i`` along axis ``d`` sits at
    ``lower[d] + i * spacing[d]``, so the first and last nodes lie on the box limits."""

    lower: tuple[float, ...]
    upper: tuple[float, ...]
    shape: tuple[int, ...]

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        if not (len(self.lower) == len(self.upper) == len(self.shape) >= 1):
            raise GridError(
                f"lower {self.lower}, upper {self.upper} and shape {self.shape} must have the "
                "same length >= 1"
            )
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            raise GridError(f"need finite lower < upper, got lower {self.lower} upper {self.upper}")
        if any(int(s) < 2 for s in self.shape):
            raise GridError(f"every grid side needs >= 2 nodes, got shape {self.shape}")
        object.__setattr__(self, "lower", tuple(float(x) for x in lo))
        object.__setattr__(self, "upper", tuple(float(x) for x in hi))
        object.__setattr__(self, "shape", tuple(int(s) for s in self.shape))

    @property
    def ndim(self) -> int:
        """Dimension of the configuration space."""
        return len(self.shape)

    @property
    def spacing(self) -> NDArray[np.float64]:
        """Distance between neighbouring nodes along each axis."""
        return (np.asarray(self.upper) - np.asarray(self.lower)) / (np.asarray(self.shape) - 1)

    def to_grid(self, q: ArrayLike) -> NDArray[np.float64]:
        """Continuous grid coordinates (node ``i`` at ``i``) of configurations ``q`` (..., n)."""
        return (np.asarray(q, float) - np.asarray(self.lower)) / self.spacing

    def to_config(self, x: ArrayLike) -> NDArray[np.float64]:
        """Configurations of continuous grid coordinates ``x`` (..., n)."""
        return np.asarray(self.lower) + np.asarray(x, float) * self.spacing

    def nearest_cell(self, q: ArrayLike) -> tuple[int, ...]:
        """Index of the node nearest to configuration ``q`` (clipped into the grid)."""
        idx = np.clip(np.rint(self.to_grid(q)), 0, np.asarray(self.shape) - 1).astype(int)
        return tuple(int(i) for i in idx)

    def node_configs(self) -> NDArray[np.float64]:
        """All node configurations, shape ``(prod(shape), n)`` in C order of the grid."""
        idx = np.indices(self.shape).reshape(self.ndim, -1).T
        return self.to_config(idx)

    def contains(self, q: ArrayLike) -> bool:
        """Whether configuration ``q`` lies inside the grid's box."""
        q = np.asarray(q, float)
        return bool(np.all(q >= np.asarray(self.lower)) and np.all(q <= np.asarray(self.upper)))


@dataclass(frozen=True, eq=False)
class HarmonicField:
    """The solved potential. ``log_phi = log(1 - u)``: 0 on goal cells, ``-inf`` on obstacle
    cells and on free cells whose face-connected component holds no goal (no path from there)."""

    log_phi: NDArray[np.float64]  #: shape of the grid
    free: NDArray[np.bool_]  #: cells that are not obstacles
    goal: NDArray[np.bool_]  #: goal cells actually used (free goal cells)
    n_unknowns: int  #: free cells solved for (connected to a goal, not goals themselves)
    n_levels: int  #: rescaled solves needed (1 unless the potential went flat)
    cg_iterations: int  #: total conjugate-gradient iterations

    @property
    def shape(self) -> tuple[int, ...]:
        """Grid shape."""
        return self.log_phi.shape

    def reachable(self, cell: tuple[int, ...]) -> bool:
        """Whether a path to a goal exists from grid cell ``cell``."""
        return bool(np.isfinite(self.log_phi[tuple(cell)]))

    @property
    def u(self) -> NDArray[np.float64]:
        """The classic harmonic potential ``u = 1 - phi`` (flat far from the goal in float64)."""
        return 1.0 - np.exp(self.log_phi)


@dataclass(frozen=True, eq=False)
class HarmonicPath:
    """A path found by ascending ``log(phi)``; ``points`` in grid coordinates, ``(k, n)``."""

    found: bool  #: whether the path ends in a goal cell
    points: NDArray[np.float64]  #: start first; ends at the centre of a goal cell if found
    reason: str  #: "reached goal", or why no path was returned
    n_discrete_steps: int  #: steps taken cell-to-cell where the interpolated gradient stalled

    @property
    def length(self) -> float:
        """Polyline length in grid units."""
        if len(self.points) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def _face_pairs(region: NDArray[np.bool_]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Flat index pairs ``(p, p + stride)`` of face neighbours, both inside ``region``."""
    shape = region.shape
    flat = region.ravel()
    strides = np.cumprod((1, *shape[::-1]))[:-1][::-1]
    idx = np.flatnonzero(flat)
    cells = np.unravel_index(idx, shape)
    a_all, b_all = [], []
    for axis, stride in enumerate(strides):
        inner = cells[axis] < shape[axis] - 1
        a = idx[inner]
        b = a + stride
        keep = flat[b]
        a_all.append(a[keep])
        b_all.append(b[keep])
    return np.concatenate(a_all), np.concatenate(b_all)


def _neighbour_sum(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum over the 2n face neighbours of every cell; cells outside the grid count 0."""
    out = np.zeros_like(values)
    for axis in range(values.ndim):
        lo = [slice(None)] * values.ndim
        hi = [slice(None)] * values.ndim
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        out[tuple(lo)] += values[tuple(hi)]
        out[tuple(hi)] += values[tuple(lo)]
    return out


def _solve_dirichlet(
    region: NDArray[np.bool_], boundary: NDArray[np.float64], rtol: float
) -> tuple[NDArray[np.float64], int]:
    """Solve the discrete Laplace equation on ``region`` with Dirichlet values ``boundary``
    (zero inside the region and on obstacles). Returns the solution on the region's cells (C
    order) and the CG iteration count."""
    ndim = region.ndim
    idx = np.flatnonzero(region.ravel())
    m = idx.size
    local = np.full(region.size, -1, dtype=np.int64)
    local[idx] = np.arange(m)
    a, b = _face_pairs(region)
    ia, ib = local[a], local[b]
    rows = np.concatenate([np.arange(m), ia, ib])
    cols = np.concatenate([np.arange(m), ib, ia])
    vals = np.concatenate([np.full(m, 2.0 * ndim), -np.ones(2 * ia.size)])
    A = sp.csr_matrix((vals, (rows, cols)), shape=(m, m))
    rhs = _neighbour_sum(boundary).ravel()[idx]
    maxiter = CG_MAXITER_PER_SIDE * max(region.shape) + 100
    x, iterations, converged = _conjugate_gradient(A, rhs, rtol, maxiter)
    if not converged:  # fall back to a direct solve (small or pathological systems)
        x = spla.spsolve(A.tocsc(), rhs)
    return np.maximum(x, 0.0), iterations


def _conjugate_gradient(
    A: sp.csr_matrix, b: NDArray[np.float64], rtol: float, maxiter: int
) -> tuple[NDArray[np.float64], int, bool]:
    """Plain conjugate gradients for the symmetric positive definite ``A``. Inner products use
    ``numpy.sum`` rather than BLAS ``dot``: multithreaded BLAS on small vectors spins and is ~30x
    slower on a shared 2-core machine."""
    x = np.zeros_like(b)
    r = b.copy()
    p = r.copy()
    rr = float((r * r).sum())
    stop = (rtol**2) * rr
    if rr == 0.0:
        return x, 0, True
    for k in range(1, maxiter + 1):
        Ap = A @ p
        alpha = rr / float((p * Ap).sum())
        x += alpha * p
        r -= alpha * Ap
        rr_new = float((r * r).sum())
        if rr_new <= stop:
            return x, k, True
        p *= rr_new / rr
        p += r
        rr = rr_new
    return x, maxiter, False


def solve_harmonic(
    free: ArrayLike,
    goal: ArrayLike,
    *,
    rtol: float = CG_RTOL,
    threshold: float = RESCALE_THRESHOLD,
) -> HarmonicField:
    """Solve for the harmonic potential of a grid (Connolly & Grupen).

    ``free`` (bool, any n-D shape) marks cells that are not obstacles; ``goal`` (same shape)
    marks goal cells (goal cells inside obstacles are ignored). Returns ``log(phi)``, ``phi = 1-u``,
    accurate in relative terms everywhere (see the module docstring on flat potentials).
    """
    free = np.asarray(free)
    goal = np.asarray(goal)
    if free.shape != goal.shape:
        raise GridError(f"free {free.shape} and goal {goal.shape} masks differ in shape")
    if free.ndim < 1 or free.size == 0:
        raise GridError(f"grid must be non-empty, got shape {free.shape}")
    if not 0.0 < threshold < 1e-2:
        raise GridError(f"rescale threshold must lie in (0, 1e-2), got {threshold}")
    free = free.astype(bool)
    goal = goal.astype(bool) & free

    labels, _ = ndi.label(free, structure=ndi.generate_binary_structure(free.ndim, 1))
    goal_labels = np.unique(labels[goal])
    connected = np.isin(labels, goal_labels[goal_labels > 0])
    log_phi = np.full(free.shape, -np.inf)
    log_phi[goal] = 0.0
    region = connected & ~goal
    n_unknowns = int(region.sum())
    offset = 0.0  # log of the scale of the current level's boundary data
    levels = iterations = 0
    log_threshold = float(np.log(threshold))
    while region.any():
        known = np.isfinite(log_phi)
        boundary = np.zeros(free.shape)
        boundary[known] = np.exp(log_phi[known] - offset)
        # only the neighbours of the region matter; far known cells may overflow harmlessly
        boundary[~np.isfinite(boundary)] = 0.0
        x, its = _solve_dirichlet(region, boundary, rtol)
        levels += 1
        iterations += its
        cells = np.flatnonzero(region.ravel())
        accept = x >= threshold
        if not accept.any():  # cannot happen for a consistent system; guard against looping
            raise GridError(f"harmonic solve made no progress on {cells.size} cells")
        flat = log_phi.ravel()
        flat[cells[accept]] = np.log(x[accept]) + offset
        log_phi = flat.reshape(free.shape)
        region = region.copy()
        region.ravel()[cells[accept]] = False
        offset += log_threshold
    return HarmonicField(
        log_phi=log_phi,
        free=free,
        goal=goal,
        n_unknowns=n_unknowns,
        n_levels=levels,
        cg_iterations=iterations,
    )


class Interpolator:
    """Multilinear interpolation of ``phi`` around a point, computed in a local scale so that
    ``log(phi)`` and its gradient stay accurate however small ``phi`` is."""

    def __init__(self, log_phi: NDArray[np.float64]) -> None:
        self.log_phi = log_phi
        self.shape = np.asarray(log_phi.shape)
        self.corners = np.array(list(itertools.product((0, 1), repeat=log_phi.ndim)))

    def __call__(self, x: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        """``log(phi(x))`` and ``grad phi(x) / phi(x)`` (= grad log phi); ``-inf`` if phi = 0."""
        base = np.floor(x).astype(int)
        base = np.clip(base, 0, self.shape - 2)
        t = x - base
        cells = base + self.corners
        inside = np.all((cells >= 0) & (cells < self.shape), axis=1)
        logs = np.full(len(cells), -np.inf)
        logs[inside] = self.log_phi[tuple(cells[inside].T)]
        top = logs.max()
        if not np.isfinite(top):
            return -np.inf, np.zeros_like(x)
        vals = np.exp(logs - top)
        factors = np.where(self.corners == 1, t, 1.0 - t)  # (2^n, n)
        weights = factors.prod(axis=1)
        value = float(vals @ weights)
        grad = np.empty_like(x)
        for d in range(len(x)):
            others = np.delete(factors, d, axis=1).prod(axis=1)
            grad[d] = vals @ (others * np.where(self.corners[:, d] == 1, 1.0, -1.0))
        if value <= 0.0:
            return -np.inf, np.zeros_like(x)
        return float(np.log(value) + top), grad / value


def _neighbour_offsets(ndim: int) -> NDArray[np.int64]:
    """All 3^n - 1 neighbour offsets, face neighbours (one non-zero entry) first."""
    offs = [o for o in itertools.product((-1, 0, 1), repeat=ndim) if any(o)]
    offs.sort(key=lambda o: sum(abs(v) for v in o))
    return np.array(offs, dtype=int)


def ascend(
    field: HarmonicField,
    start: ArrayLike,
    *,
    step: float = DEFAULT_STEP,
    max_steps: int | None = None,
) -> HarmonicPath:
    """Follow ``-grad u`` (= ascend ``log phi``) from grid coordinates ``start`` to a goal cell.

    Steps of ``step`` cells along the interpolated gradient; where that would not increase the
    potential (interpolation artefacts at cell scale) a step to the best neighbouring cell is
    taken instead, which the discrete maximum principle guarantees to exist. Returns a path with
    ``found=False`` and a reason when the start is in an obstacle or cut off from every goal.
    """
    log_phi = field.log_phi
    shape = np.asarray(log_phi.shape)
    x = np.asarray(start, dtype=float).copy()
    if x.shape != (log_phi.ndim,):
        raise GridError(f"start {x.tolist()} must have {log_phi.ndim} coordinates")
    if not (np.all(np.isfinite(x)) and np.all(x >= 0) and np.all(x <= shape - 1)):
        raise GridError(f"start {x.tolist()} lies outside the grid of shape {tuple(shape)}")
    if not 0.0 < step <= 1.0:
        raise GridError(f"step must lie in (0, 1] cells, got {step}")
    if max_steps is None:
        max_steps = int(STEPS_PER_CELL * shape.sum() / step)

    def _cell(p: NDArray[np.float64]) -> tuple[int, ...]:
        return tuple(int(i) for i in np.clip(np.rint(p), 0, shape - 1))

    c = _cell(x)
    if not field.free[c]:
        return HarmonicPath(False, x[None], "start is inside an obstacle", 0)
    if not field.goal.any():
        return HarmonicPath(False, x[None], "no free goal cell", 0)
    if not np.isfinite(log_phi[c]):
        return HarmonicPath(False, x[None], "no path: start is cut off from every goal", 0)
    interp = Interpolator(log_phi)
    offsets = _neighbour_offsets(log_phi.ndim)
    points = [x.copy()]
    discrete = 0
    value, grad = interp(x)
    if not np.isfinite(value):
        value = float(log_phi[c])
    for _ in range(max_steps):
        c = _cell(x)
        if field.goal[c]:
            centre = np.asarray(c, float)
            if not np.allclose(points[-1], centre):
                points.append(centre)
            return HarmonicPath(True, np.array(points), "reached goal", discrete)
        norm = float(np.linalg.norm(grad))
        moved = False
        if norm > 0.0 and np.isfinite(norm):
            cand = np.clip(x + step * grad / norm, 0, shape - 1)
            cand_value, cand_grad = interp(cand)
            if cand_value > value and np.isfinite(log_phi[_cell(cand)]):
                x, value, grad, moved = cand, cand_value, cand_grad, True
        if not moved:
            nbrs = np.asarray(c) + offsets
            ok = np.all((nbrs >= 0) & (nbrs < shape), axis=1)
            nbrs = nbrs[ok]
            vals = log_phi[tuple(nbrs.T)]
            face = np.abs(offsets[ok]).sum(axis=1) == 1
            best_face = int(np.argmax(np.where(face, vals, -np.inf)))
            best = best_face if vals[best_face] > log_phi[c] else int(np.argmax(vals))
            if not vals[best] > log_phi[c]:
                return HarmonicPath(False, np.array(points), "stalled at a local maximum", discrete)
            x = nbrs[best].astype(float)
            value, grad = interp(x)
            discrete += 1
        points.append(x.copy())
    return HarmonicPath(False, np.array(points), f"no goal within {max_steps} steps", discrete)
