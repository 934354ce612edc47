"""The weight solve (paper III.D, eqs. 2–4): image keypoints → library mix H → new model S·H.

The image keypoints z (pixels) are the projection of the mixed model, s·K·H + t, with the image's
unknown scale s and offset t. Three methods:

- ``"paper"``: the paper's constrained least squares, ΣH = 1, 0 ≤ H ≤ 1. Writing G = s·H turns
  the constraints into G ≥ 0 (then s = ΣG, H = G/ΣG, and H ≤ 1 follows), and centring both sides
  on their keypoint mean removes t: min ‖Kc·G − zc‖, G ≥ 0, an exact reformulation solved as
  non-negative least squares by an active set on a working set of models. The full library's
  gradient is one pass over its (35·3, N) keypoint rows, so a million models cost a few
  matrix–vector passes, never an N × N matrix or the full 840-row S.
- ``"gauss"``: a Gaussian shape prior. The library's models span a shape space with a
  mean m and principal directions B (scaled to unit variance); the new model is m + B·a, an
  affine mix of the library (ΣH = 1, weights may be negative), with a MAP estimate
  min ‖reprojection‖² + λ‖a‖². With c = s·a and g = s the problem is linear in (g, c), so one
  small (1 + q)² solve replaces the NNLS. Directions the view cannot see (x on a side view, y on
  a front view) go to their most likely value given the visible ones instead of to whichever
  library corner happens to fit, and a car outside the library's convex hull (a leave-one-out
  template) can still be reached. It halves the paper's error on the leave-one-out benchmark.
- ``"mixture"`` (default): the same covariance around each template's mean instead of the
  library mean, the components weighted by their posterior. It lets the visible part of the car
  pick which template the invisible part resembles (front and rear views gain most). All
  centres share one SVD and their scale searches run side by side, so it costs about one
  ``"gauss"`` solve; it has the lowest mean error of the three in every case of the
  leave-one-out benchmark (docs/fit_accuracy.md).

Both Gaussian-prior models carry, beside the library's directions, the local part of the
photo-matching deformation as zero-mean directions (:meth:`ShapeModel.with_field`), so the
solve can move a feature along the car instead of bending the whole mix.

The camera is SPEC's orthographic one, or a pinhole camera at a given distance, aimed at the
car's centre: its projection is linearised at the previous round's shape and the solve repeated
(Newton steps; :func:`camera_rows`, ``PERSPECTIVE_ITERATIONS``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from carbody.errors import FitError
from carbody.camera import View, view_rotation
from carbody.fit.keypoints_io import KeypointSlot

#: Default prior weight λ of the Gaussian-prior methods, dimensionless (keypoint residuals are
#: measured relative to the car's spread in the image); chosen on the leave-one-out benchmark
#: (``benchmarks/bench_fit_accuracy.py --sweep``).
DEFAULT_PRIOR_WEIGHT = 1e-4

#: Principal components kept in the shape model: enough for this fraction of the variance.
SHAPE_ENERGY = 0.99999

#: Most principal components the shape model computes.
MAX_COMPONENTS = 200

#: Newton rounds of a pinhole-camera solve (the first linearises at the library's mean car).
PERSPECTIVE_ITERATIONS = 2

#: Most Newton rounds of a full pinhole solve: more than ``rounds`` only while the camera,
#: linearised at the shape a round starts from, does not hold at the shape it finds
#: (:func:`camera_excess_px`) and each round at least halves the gap.
MAX_PERSPECTIVE_ROUNDS = 6

#: A pinhole solve has settled when its real residual exceeds its linearised one by at most this
#: share of the marks' spread (rho, the RMS of their centred pixels) ...
SETTLED_CAMERA = 0.01

#: ... or by at most this share of the linearised residual itself (marks that fit badly anyway).
SETTLED_RESIDUAL = 0.1

#: Largest perspective factor a solve uses (a point 5× nearer than the aim's distance).
MAX_PERSPECTIVE_FACTOR = 5.0

#: Passes of the Gaussian-prior solve's scale search after its log grid; each evaluates 17 scales
#: across the bracket and keeps the best's neighbours (8× narrower); a parabola through the last
#: pass's best three then places the minimum (the cost is smooth and near-quadratic there).
SCALE_PASSES = 2

#: Fit methods, default first.
METHODS = ("mixture", "gauss", "paper")

#: Libraries up to this size are solved in one active-set run over every model.
FULL_SET_MAX = 6000

#: Models added to the working set per pass (most violated optimality conditions first).
WORKING_SET_GROWTH = 400

#: Models spread evenly over the library that seed the working set.
STRIDE_SAMPLE = 2000


def keypoint_spread(keypoints: np.ndarray) -> float:
    """RMS distance of (k, 3) keypoints (or (k, 2) marks, pixels) from their centroid: a model's
    ``size``, the unit its solve measures image residuals against; the marks' spread."""
    return float(np.sqrt(np.mean(np.sum((keypoints - keypoints.mean(axis=0)) ** 2, axis=1))))


@dataclass
class KeypointBasis:
    """The library's keypoint rows, prepared once for many ``"paper"`` solves.

    Attributes:
        X: (35, 3, N) float, each model's 35 left keypoints, normalised units (float32 is fine
            for very large libraries).
        size: RMS distance of the mean model's keypoints from their centroid, normalised units.
        mean: (35, 3) float, the mean model's keypoints (where a pinhole solve starts).
    """

    X: np.ndarray
    size: float
    mean: np.ndarray | None = None

    @property
    def n_models(self) -> int:
        return self.X.shape[2]

    @classmethod
    def from_shapes(cls, S: np.ndarray, point_indices: np.ndarray, dtype=np.float64) -> "KeypointBasis":
        """Build from (840, N) normalised shape vectors and the (35,) keypoint rows."""
        X = S.reshape(-1, 3, S.shape[1])[point_indices]
        return cls.from_keypoints(X.astype(dtype, copy=False))

    @classmethod
    def from_keypoints(cls, X: np.ndarray) -> "KeypointBasis":
        """Build from (35, 3, N) keypoint coordinates (normalised units)."""
        m = X.mean(axis=2, dtype=np.float64)
        return cls(X=X, size=keypoint_spread(m), mean=m)


@dataclass
class ShapeModel:
    """The library as a Gaussian shape space (``"gauss"`` method).

    Attributes:
        mean: (840,) float, mean shape vector, normalised units.
        basis: (840, q) float, principal directions scaled by their standard deviation, so a
            shape m + basis·a has a ~ N(0, I) over the library.
        size: as :attr:`KeypointBasis.size`.
        to_weights: (N, q₀) float or None, maps a's first q₀ coefficients (the library's
            directions; any after them are a field's, :meth:`with_field`) to affine library
            weights H − weight_offset (reports).
        group_means: (T, q) float or None, each template's mean coefficients (the centres of
            the ``"mixture"`` prior).
        weight_offset: (N,) float or None, the weights of the model's mean shape: 1/N for every
            model (None), or 1/n for the n it was built from and 0 for the rest.
    """

    mean: np.ndarray
    basis: np.ndarray
    size: float
    to_weights: np.ndarray | None = None
    group_means: np.ndarray | None = None
    weight_offset: np.ndarray | None = None

    def weights(self, a: np.ndarray) -> np.ndarray | None:
        """(N,) affine library weights (ΣH = 1) that reproduce the shape mean + basis·a."""
        if self.to_weights is None:
            return None
        offset = 1.0 / len(self.to_weights) if self.weight_offset is None else self.weight_offset
        return offset + self.to_weights @ a[:self.to_weights.shape[1]]

    def with_field(self, field: np.ndarray) -> "ShapeModel":
        """The model with extra zero-mean directions (a displacement field's basis, (840, q'),
        each column one standard deviation): shape = mean + basis·a + field·c with c ~ N(0, I)
        like a, solved with it. The weights stay the library part's (c adds none)."""
        return ShapeModel(mean=self.mean, basis=np.hstack([self.basis, field]), size=self.size,
                          to_weights=self.to_weights, weight_offset=self.weight_offset,
                          group_means=None if self.group_means is None else
                          np.hstack([self.group_means, np.zeros((len(self.group_means), field.shape[1]))]))

    @classmethod
    def from_shapes(cls, S: np.ndarray, point_indices: np.ndarray, with_weights: bool = True,
                    groups: np.ndarray | None = None, keep: np.ndarray | None = None) -> "ShapeModel":
        """Principal components of (840, N) normalised shapes (covariance in column chunks).

        Args:
            groups: (N,) int, each model's template, for the ``"mixture"`` prior's centres.
            keep: (N,) bool, the models the statistics are taken over (default all); the
                weights still index all N, zero on the others.
        """
        every, templates = S.shape[1], None if groups is None else int(groups.max()) + 1
        if keep is not None:
            S, groups = S[:, keep], None if groups is None else groups[keep]
        n = S.shape[1]
        mean = S.mean(axis=1, dtype=np.float64)
        cov = np.zeros((S.shape[0], S.shape[0]))
        for a in range(0, n, 100_000):
            block = S[:, a:a + 100_000].astype(np.float64) - mean[:, None]
            cov += block @ block.T
        cov /= n
        from scipy.linalg import eigh

        # Only the leading directions matter (the expansions are low rank): a partial eigh.
        top = min(len(cov), MAX_COMPONENTS)
        evals, evecs = eigh(cov, subset_by_index=[len(cov) - top, len(cov) - 1], driver="evr")
        total = float(np.trace(cov))
        evals, evecs = np.clip(evals[::-1], 1e-300, None), evecs[:, ::-1]
        q = min(int(np.searchsorted(np.cumsum(evals) / total, SHAPE_ENERGY)) + 1, top)
        basis = evecs[:, :q] * np.sqrt(evals[:q])
        to_w, centres = None, None
        if with_weights or groups is not None:
            # Whitened coefficients of every model; H = 1/N + coeffs·a / N reproduces m + basis·a.
            coeffs = ((S.T.astype(np.float64) @ (evecs[:, :q] / np.sqrt(evals[:q])))
                      - mean @ (evecs[:, :q] / np.sqrt(evals[:q])))
            to_w = coeffs / n if with_weights else None
            if groups is not None:
                count = np.bincount(groups, minlength=templates)
                centres = np.stack([np.bincount(groups, weights=c, minlength=templates)
                                    for c in coeffs.T], axis=1) / np.maximum(count, 1)[:, None]
        offset = None
        if keep is not None and to_w is not None:
            full = np.zeros((every, q))
            full[keep] = to_w
            to_w, offset = full, np.where(keep, 1.0 / n, 0.0)
        return cls(mean=mean, basis=basis, size=keypoint_spread(mean.reshape(-1, 3)[point_indices]),
                   to_weights=to_w, group_means=centres,
                   weight_offset=offset)


@dataclass
class MixSolution:
    """Result of one solve at a fixed view.

    Attributes:
        shape: (840,) float, the new model's shape vector, normalised units (S·H); None when
            :func:`solve_simplex` was not given S.
        weights: (N,) float, library weights, ΣH = 1 (``"paper"``: 0 ≤ H ≤ 1 and sparse), or
            None until first asked for as ``H`` (``weights_of`` computes them).
        scale: s, pixels per normalised unit.
        offset: (2,) float, (u0, v0) pixels of the car-frame origin.
        residual_px: (k,) float, reprojection distance per keypoint, pixels.
        cost: the minimised objective (data + prior), dimensionless.
        residual_vector: the stacked residuals whose squared norm is ``cost``.
        support: models with positive weight (``"paper"``; used to warm-start the next solve).
        evidence: −log marginal likelihood of the view with the shape integrated out, up to a
            constant (``"gauss"``/``"mixture"``; the view refinement minimises it).
        view: the camera solved with (a pinhole view's aim moved onto the car's centre).
        posterior: how far the shape is pinned (``"gauss"``/``"mixture"``): a
            :class:`ShapePosterior`, from which :func:`keypoint_covariance` gives each
            keypoint's uncertainty.
        evidence_px: −log density of the marks' pixels (nats): ``evidence`` with its normalising
            terms (λ's noise and the marks' spread ρ), so fits of different sets of marks
            compare (:mod:`carbody.fit.hypothesis`).
        leverage: (k, 2, 2) the hat matrix's diagonal blocks: how much of each mark's (u, v)
            its own fit follows (the leave-one-out residual is (I − leverage)⁻¹ · residual).
        rho: the marks' RMS spread about their centre per coordinate, px (the solve's unit).
    """

    shape: np.ndarray | None
    weights: np.ndarray | None
    scale: float
    offset: np.ndarray
    residual_px: np.ndarray
    cost: float
    residual_vector: np.ndarray
    support: np.ndarray | None = None
    evidence: float | None = None
    view: View | None = None
    posterior: "ShapePosterior | None" = None
    evidence_px: float | None = None
    leverage: np.ndarray | None = None
    rho: float | None = None
    weights_of: "Callable[[], np.ndarray | None] | None" = field(default=None, repr=False)

    @property
    def H(self) -> np.ndarray | None:
        """(N,) library weights, computed when first asked (the search's hundreds of solves
        never need them: one product of a library-sized matrix each)."""
        if self.weights is None and self.weights_of is not None:
            self.weights = self.weights_of()
        return self.weights


class ScaleSolve(NamedTuple):
    """The pieces of a Gaussian-prior solve that :func:`scale_trade` solves again at other image
    scales: each prior centre's centred projection ``ams`` (T, m), the projected basis ``AB``
    (m, q), the image ``b`` (m,), each centre's scale ``scales`` (T,) and coefficients
    ``centres`` (T, q), and the shape basis (840, q) that turns coefficients into a shape."""

    ams: np.ndarray
    AB: np.ndarray
    b: np.ndarray
    scales: np.ndarray
    centres: np.ndarray
    basis: np.ndarray


@dataclass
class ShapePosterior:
    """The Gaussian-prior solve's posterior over the shape coefficients a, kept as the solve's
    own pieces (the covariance is built only when asked, :func:`keypoint_covariance`).

    Each prior centre t gives a Gaussian posterior N(a_t, Σ) with
    Σ = V·diag(λ / (λ + g²e))·Vᵀ + (I − V·Vᵀ): directions the image sees (the right singular
    vectors V of the projected basis, squared singular values e) narrowed by the data, the
    others left at the prior's unit variance. The mixture's posterior is the components
    weighted by ``weights``: its covariance adds their spread about the mean, and the shape's
    trade with the image scale (:func:`scale_spread`). When the marks fit worse than λ's noise
    allows (a car unlike the library, a misplaced mark), the whole covariance is scaled by
    ``inflation`` = cost / (λ · data rows), never below 1.

    Attributes:
        V: (q, r) right singular vectors; e: (r,) squared singular values; lam: λ.
        g: the image scale in the solve's units (the weighted mean over centres).
        centres: (T, q) each component's posterior mean a_t; weights: (T,), sum 1.
        keypoint_basis: (3·35, q) the shape basis' keypoint rows (a's effect on the keypoints).
        inflation: the covariance's scale factor (≥ 1).
        view_spread: (n, 3·35) or None: each refined view angle's share, the keypoints' move
            per one standard deviation of that angle (:func:`carbody.fit.search.view_spread` adds it
            after the refinement); its outer products join the covariance.
        scale_solve: the solve's pieces that :func:`scale_trade` reads (:class:`ScaleSolve`),
            or None: the image scale taken as known.
    """

    V: np.ndarray
    e: np.ndarray
    lam: float
    g: float
    centres: np.ndarray
    weights: np.ndarray
    keypoint_basis: np.ndarray
    inflation: float = 1.0
    view_spread: np.ndarray | None = None
    scale_solve: ScaleSolve | None = None
    _trade: tuple | None = field(default=None, init=False, repr=False)  # scale_trade's, once


def nnls_active_set(A: np.ndarray, b: np.ndarray, passive: np.ndarray | None = None,
                    tol: float = 1e-10, max_iter: int | None = None) -> np.ndarray:
    """min ‖A·x − b‖ subject to x ≥ 0 (Lawson–Hanson active set).

    Args:
        A: (m, n) float.
        b: (m,) float.
        passive: optional (p,) int, columns to start from (a warm start).
        tol: stop when no zero column's gradient exceeds ``tol`` × the largest initial one.
    Returns:
        (n,) float, x ≥ 0.
    """
    m, n = A.shape
    x = np.zeros(n)
    P = np.zeros(n, dtype=bool)
    if passive is not None and len(passive):
        P[np.asarray(passive)] = True
        x = _feasible_start(A, b, P)
    w = A.T @ (b - A @ x)
    scale = max(float(np.max(np.abs(A.T @ b))), 1e-300)
    max_iter = max_iter or 3 * max(m, 10) + 2 * (0 if passive is None else len(passive))
    for _ in range(max_iter):
        w_free = np.where(P, -np.inf, w)
        j = int(np.argmax(w_free))
        if not w_free[j] > tol * scale:
            break
        P[j] = True
        while True:
            idx = np.flatnonzero(P)
            z = _lstsq(A[:, idx], b)
            if np.all(z > 0):
                x[:] = 0.0
                x[idx] = z
                break
            xi = x[idx]
            neg = z <= 0
            if neg.sum() == 1 and idx[neg][0] == j and xi[neg][0] == 0:
                P[j] = False  # numerically dependent column: it cannot enter
                break
            alpha = np.min(xi[neg] / (xi[neg] - z[neg]))
            x[idx] = xi + alpha * (z - xi)
            drop = idx[(x[idx] <= 1e-14 * max(1.0, np.max(x[idx])))]
            P[drop] = False
            x[~P] = 0.0
            if not P.any():
                break
        if not P[j] and x[j] == 0 and w_free[j] > tol * scale and np.flatnonzero(P).size == 0:
            break
        w = A.T @ (b - A[:, P] @ x[P])
    return x


def _lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares on a small dense block (normal equations, QR fallback)."""
    g = A.T @ A
    try:
        c = np.linalg.cholesky(g + 1e-13 * np.trace(g) / len(g) * np.eye(len(g)))
        y = np.linalg.solve(c, A.T @ b)
        return np.linalg.solve(c.T, y)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def _feasible_start(A: np.ndarray, b: np.ndarray, P: np.ndarray) -> np.ndarray:
    """A feasible x supported on (a subset of) P: LS on P, dropping negatives until none."""
    x = np.zeros(A.shape[1])
    for _ in range(int(P.sum()) + 1):
        idx = np.flatnonzero(P)
        if not len(idx):
            break
        z = _lstsq(A[:, idx], b)
        if np.all(z > 0):
            x[idx] = z
            break
        P[idx[z <= 0]] = False
    return x


def projection_rows(slots: list[KeypointSlot], view: View) -> np.ndarray:
    """(2k, 35, 3) float: row 2i (2i+1) maps the 35 keypoints to u (v, down) of slot i, scale 1."""
    rot = view_rotation(view)
    kp, sign = _slot_arrays(slots)
    return _rows(kp, rot[1] * sign, -rot[2] * sign)


def _slot_arrays(slots: list[KeypointSlot]) -> tuple[np.ndarray, np.ndarray]:
    """((k,) int keypoint row of each slot (its id − 1), (k, 3) float their signs)."""
    return np.array([s.keypoint_id - 1 for s in slots]), np.array([s.sign for s in slots])


def _rows(kp: np.ndarray, u_rows: np.ndarray, v_rows: np.ndarray) -> np.ndarray:
    """(2k, 35, 3) float, zero but row 2i (2i+1) at keypoint kp[i]: u_rows[i] (v_rows[i])."""
    M = np.zeros((2 * len(kp), 35, 3))
    M[0::2][np.arange(len(kp)), kp] = u_rows
    M[1::2][np.arange(len(kp)), kp] = v_rows
    return M


def camera_rows(slots: list[KeypointSlot], view: View, keypoints: np.ndarray | None = None):
    """The camera as a linear map of the 35 keypoints: image coordinates at scale 1 are
    M·X + const (exact for an orthographic view; a pinhole view is linearised at ``keypoints``,
    (35, 3): its first-order Taylor expansion there, so repeated solves are Newton steps).

    Returns:
        (M (2k, 35, 3) float, const (2k,) float).
    """
    if view.distance is None:
        M = projection_rows(slots, view)
        return M, np.zeros(len(M))
    kp, sign = _slot_arrays(slots)
    grad, offset = point_camera(keypoints[kp] * sign, view)
    return _rows(kp, grad[:, 0] * sign, grad[:, 1] * sign), offset.ravel()


def point_camera(points: np.ndarray, view: View) -> tuple[np.ndarray, np.ndarray]:
    """The camera linearised at car-frame points (n, 3): image coordinates at scale 1 near
    point i are grad[i]·p + const[i] (exact for an orthographic view).

    Returns:
        (grad (n, 2, 3) float, const (n, 2) float): u and v (down) rows.
    """
    rot = view_rotation(view)
    pts = np.asarray(points, dtype=float)
    grad = np.broadcast_to(np.stack([rot[1], -rot[2]]), (len(pts), 2, 3)).copy()
    const = np.zeros((len(pts), 2))
    if view.distance is None:
        return grad, const
    from carbody.camera import camera_direction, perspective_factors

    # A stray intermediate shape may reach the camera; its evidence will tell, so clamp.
    k = perspective_factors(pts, view, max_factor=MAX_PERSPECTIVE_FACTOR)
    aim, d = np.asarray(view.aim, dtype=float), camera_direction(view)
    # u(p) = aim·r + k(p)·(p − aim)·r with k(p) = D / (D − (p − aim)·d), so
    # ∂u/∂p = k·r + (k²/D)·((p − aim)·r)·d (zero slope where k is clamped); v likewise with −w.
    slope = np.where(k < MAX_PERSPECTIVE_FACTOR, k * k / view.distance, 0.0)
    for axis, row, flip in ((0, rot[1], 1.0), (1, rot[2], -1.0)):
        offset = (pts - aim) @ row
        g = k[:, None] * row + (slope * offset)[:, None] * d  # (n, 3) with respect to p
        grad[:, axis] = flip * g
        const[:, axis] = flip * (aim @ row + k * offset - np.einsum("ij,ij->i", g, pts))
    return grad, const


def _centred(slots: list[KeypointSlot], uv: np.ndarray, view: View, keypoints: np.ndarray | None = None):
    """Camera rows and image coordinates centred per image axis (this removes the offset).

    Returns:
        (M, const, Mc (2k, 105), const centred (2k,), z (k, 2), centred image / rho, rho).
    """
    M, const = camera_rows(slots, view, keypoints)
    Mc, cc = M.copy(), const.copy()
    for axis in (0, 1):
        Mc[axis::2] -= M[axis::2].mean(axis=0)
        cc[axis::2] -= const[axis::2].mean()
    z = np.asarray(uv, dtype=float)
    zc = (z - z.mean(axis=0)).ravel()
    rho = float(np.sqrt(np.mean(zc**2)))
    if not rho > 0:
        raise FitError("the keypoints are coincident")
    return M, const, Mc.reshape(len(M), -1), cc, z, zc / rho, rho


def _image_fit(M: np.ndarray, keypoints: np.ndarray, z: np.ndarray, scale: float,
               const: np.ndarray | None = None):
    """Offset, predicted pixels and residual of a model's keypoints (35, 3) at a given scale."""
    proj = np.einsum("rkc,kc->r", M, keypoints)
    if const is not None:
        proj = proj + const
    proj = proj.reshape(-1, 2)  # (u − u0, v − v0) at scale 1
    offset = z.mean(axis=0) - scale * proj.mean(axis=0)
    pred = offset + scale * proj
    return offset, pred


def solve_simplex(basis: KeypointBasis, slots: list[KeypointSlot], uv: np.ndarray, view: View,
                  shapes: np.ndarray | None = None, warm_support: np.ndarray | None = None,
                  rounds: int = PERSPECTIVE_ITERATIONS, full_set_max: int = FULL_SET_MAX,
                  working_set_growth: int = WORKING_SET_GROWTH) -> MixSolution:
    """The paper's constrained solve (ΣH = 1, 0 ≤ H ≤ 1) with the image's scale and offset.

    Args:
        basis: the library's keypoint rows.
        slots: the k annotated keypoints; uv: (k, 2) float, their pixels.
        view: the camera. A pinhole view is solved as in :func:`solve_gauss`, by rounds that
            linearise the camera at the previous mix (and, given ``shapes``, aim at its
            centre).
        shapes: (840, N) float, the library's S, to return the new model S·H (else ``shape``
            is None).
        warm_support: models to start the active set from (a previous solution's support).
        rounds: a pinhole view's Newton rounds (1: linearised at the library's mean car only,
            the search's cheap solve).
        full_set_max, working_set_growth: libraries up to ``full_set_max`` models are solved in
            one active-set run; larger ones on a working set grown by ``working_set_growth``.
    Raises:
        FitError: keypoints no library mix reproduces at a positive image scale.
    """
    from dataclasses import replace

    kp = basis.mean  # a pinhole's first linearisation: the mean car
    rounds = 1 if view.distance is None else rounds
    for round_ in range(rounds):
        M, const, Mc, cc, z, b, rho = _centred(slots, uv, view, kp)
        G = _solve_working_set(basis, Mc / basis.size, cc / basis.size, b, warm_support, slots, M,
                               full_set_max, working_set_growth)
        total = G.sum()
        if not total > 0:
            raise FitError("no library mix reproduces these keypoints at a positive image scale "
                           "(check the view angle and which side each keypoint name is on)")
        H = G / total
        support = warm_support = np.flatnonzero(H > 0)
        kp = np.tensordot(basis.X[:, :, support].astype(np.float64), H[support], axes=([2], [0]))
        if round_ + 1 < rounds and shapes is not None:  # the next round aims at this mix's centre
            view = replace(view, aim=car_centre(shapes[:, support] @ H[support]))
    scale = total * rho / basis.size
    if view.distance is not None:  # the residual of the camera itself, not of its last linearisation
        M, const = camera_rows(slots, view, kp)
    offset, pred = _image_fit(M, kp, z, scale, const)
    rvec = ((pred - z) / rho).ravel()
    shape = shapes[:, support] @ H[support] if shapes is not None else None
    return MixSolution(shape=shape, weights=H, scale=float(scale), offset=offset,
                       residual_px=np.linalg.norm(pred - z, axis=1), cost=float(rvec @ rvec),
                       residual_vector=rvec, support=support, view=view)


def solve_gauss(model: ShapeModel, point_indices: np.ndarray, slots: list[KeypointSlot],
                uv: np.ndarray, view: View, prior_weight: float = DEFAULT_PRIOR_WEIGHT,
                mixture: bool = False, rounds: int = PERSPECTIVE_ITERATIONS,
                outline: "OutlineTargets | None" = None, hubs: "HubTargets | None" = None) -> MixSolution:
    """MAP shape under the library's Gaussian shape prior, with the image's scale and offset.

    Args:
        model: the library's shape model.
        point_indices: (35,) int, control-point row of each keypoint.
        slots, uv, view: as :func:`solve_simplex`.
        prior_weight: λ.
        mixture: a mixture prior, one Gaussian (the library's covariance) around each template's
            mean, combined by their posterior weights (``"mixture"`` method).
        rounds: a pinhole view's Newton rounds (below).
        outline: points of the curves matched to the car's outline in the photo
            (:class:`carbody.fit.outline.OutlineTargets`), pseudo-observations of their own
            noise: each pins its point's projection along the outline's normal. The image
            offset stays the marks' (the outline rows are centred on the marks' mean).
        hubs: the wheels' hubs found in the photo (:class:`carbody.fit.wheels.HubTargets`),
            pseudo-observations like the outline's, each with its own noise.

    A pinhole view (``view.distance``) is aimed at the car's centre and solved by Newton rounds:
    linearise the camera and set the aim at the current shape, solve, repeat
    (``rounds``, default ``PERSPECTIVE_ITERATIONS``); the solution's ``view`` carries the final aim.
    A full solve (``rounds`` ≥ 2) goes on, up to ``MAX_PERSPECTIVE_ROUNDS``, while the camera
    linearised at a round's start does not hold at the shape it found (:func:`camera_excess_px`):
    its residual and evidence are then the real camera's, not a linear camera's that no car
    meets. A close camera with a car bent toward it needs this; a far one settles in two.
    """
    from dataclasses import replace

    if hubs is not None and hubs.directions is not None:  # what only the hubs show (the ride height)
        model = model.with_field(hubs.directions)
    q = model.basis.shape[1]
    mk = model.mean.reshape(-1, 3)[point_indices].ravel()
    Bk = model.basis.reshape(-1, 3, q)[point_indices].reshape(-1, q)
    shape = model.mean
    if view.distance is None:
        most = 1  # an orthographic camera is linear
    elif rounds < 2:
        most = rounds  # the search's cheap solve: the camera linearised at the mean car only
    else:
        most = max(rounds, MAX_PERSPECTIVE_ROUNDS)
    excess_before = np.inf
    for round_ in range(most):
        if view.distance is not None:
            view = replace(view, aim=car_centre(shape))
        sol = _solve_gauss_linear(model, mk, Bk, point_indices, slots, uv, view, shape, prior_weight, mixture,
                                  outline, hubs)
        shape = sol.shape
        if round_ + 1 >= rounds:
            if view.distance is None:
                break
            excess = camera_excess_px(sol, slots, uv, view, point_indices) / sol.rho
            # settled (the gap is small beside the marks' spread or beside the residual itself),
            # or the rounds no longer halve it (marks no car meets there: more rounds would not
            # settle it, and the search's camera check judges the solve)
            settled = max(SETTLED_CAMERA, SETTLED_RESIDUAL * float(sol.residual_px.mean()) / sol.rho)
            if excess <= settled or excess > 0.5 * excess_before:
                break
            excess_before = excess
    sol.view = view
    return sol


def camera_excess_px(sol: MixSolution, slots: list[KeypointSlot], uv: np.ndarray, view: View,
                     point_indices: np.ndarray) -> float:
    """How far a pinhole solve's camera, linearised at the shape it started from, misses the
    real one at the shape it found, px: the marks' mean residual through the camera linearised
    there (exactly the real camera at that shape) less the solve's."""
    kp = sol.shape.reshape(-1, 3)[point_indices]
    M, const = camera_rows(slots, view, kp)
    z = np.asarray(uv, dtype=float)
    _, pred = _image_fit(M, kp, z, sol.scale, const)
    real = np.linalg.norm(pred - z, axis=1)
    return float(real.mean() - sol.residual_px.mean())


def reaches_camera(shape: np.ndarray, view: View) -> bool:
    """Whether part of a car (``shape``: its left half, (840,) or (280, 3); the mirror is checked
    too) lies at or behind a pinhole ``view``'s camera. A solve's perspective is clamped
    (:data:`MAX_PERSPECTIVE_FACTOR`), so a solve can pull a car through a close camera when
    what it follows contradicts itself there; such a car cannot be drawn. False for an
    orthographic view."""
    from carbody.camera import perspective_factors
    from carbody.errors import AngleError
    from carbody.wireframe import MIRROR

    if view.distance is None:
        return False
    points = np.asarray(shape, dtype=float).reshape(-1, 3)
    try:
        perspective_factors(np.concatenate([points, points * MIRROR]), view)
    except AngleError:
        return True
    return False


def car_centre(shape: np.ndarray) -> tuple[float, float, float]:
    """The centre of a car's bounding box (both halves: x = 0), the point a photo is aimed at."""
    points = np.asarray(shape).reshape(-1, 3)
    return (0.0, float(points[:, 1].min() + points[:, 1].max()) / 2,
            float(points[:, 2].min() + points[:, 2].max()) / 2)


def _solve_gauss_linear(model: ShapeModel, mk: np.ndarray, Bk: np.ndarray, point_indices: np.ndarray,
                        slots: list[KeypointSlot], uv: np.ndarray, view: View, guess: np.ndarray,
                        prior_weight: float, mixture: bool, outline=None, hubs=None) -> MixSolution:
    """:func:`solve_gauss` with the camera linearised at the shape ``guess`` (840,)."""
    M, const, Mc, cc, z, b, rho = _centred(slots, uv, view, guess.reshape(-1, 3)[point_indices])
    AB = (Mc @ Bk) / model.size
    am = (Mc @ mk + cc) / model.size
    marks_rows = len(b)
    for pseudo in (outline, hubs):
        if pseudo is not None and len(pseudo):
            L, c, target = _outline_rows(pseudo, M, const, z, view, guess, point_indices)
            w = 1.0 / np.broadcast_to(np.asarray(pseudo.noise_ratio, dtype=float), len(target))
            AB = np.vstack([AB, w[:, None] * (L @ model.basis) / model.size])
            am = np.concatenate([am, w * (L @ model.mean + c) / model.size])
            b = np.concatenate([b, w * target / rho])
    if mixture and model.group_means is not None:
        # One Gaussian per template centre, shared covariance; the posterior mean of the mixture.
        ams = am + model.group_means @ AB.T
        deltas, gs, _, nle, (V, e) = _map_coefficients(ams, AB, b, prior_weight)
        w = np.exp(-(nle - nle.min()))
        evidence = float(nle.min() - np.log(w.mean()))
        w /= w.sum()
        delta = w @ deltas
        a = w @ model.group_means + delta
        g = float(w @ gs)
        prior_part = np.sqrt(prior_weight) * delta
        posterior = ShapePosterior(V, e, prior_weight, g, model.group_means + deltas, w, Bk,
                                   scale_solve=ScaleSolve(ams, AB, b, gs, model.group_means, model.basis))
    else:
        a, g, _, evidence, (V, e) = _map_coefficients(am, AB, b, prior_weight)
        a, g, evidence = a[0], float(g[0]), float(evidence[0])
        prior_part = np.sqrt(prior_weight) * a
        posterior = ShapePosterior(V, e, prior_weight, g, a[None], np.ones(1), Bk,
                                   scale_solve=ScaleSolve(am[None], AB, b, np.array([g]), np.zeros((1, len(a))),
                                                          model.basis))
    if not g > 0:
        raise FitError("no shape reproduces these keypoints at a positive image scale "
                       "(check the view angle and which side each keypoint name is on)")
    shape = model.mean + model.basis @ a
    scale = g * rho / model.size
    offset, pred = _image_fit(M, shape.reshape(-1, 3)[point_indices], z, scale, const)
    rvec = np.concatenate([((pred - z) / rho).ravel(), prior_part])  # the marks' (and the prior's)
    # the centred image has 2k − 2 free rows
    posterior.inflation = max(1.0, float(rvec @ rvec) / (prior_weight * max(2 * len(z) - 2, 1)))
    m = 2 * len(z) - 2
    return MixSolution(shape=shape, weights=None, weights_of=lambda: model.weights(a), scale=float(scale), offset=offset,
                       residual_px=np.linalg.norm(pred - z, axis=1), cost=float(rvec @ rvec),
                       residual_vector=rvec, evidence=evidence, posterior=posterior,
                       evidence_px=evidence + 0.5 * m * np.log(2.0 * np.pi * prior_weight) + m * np.log(rho),
                       leverage=_leverage(AB[:marks_rows] @ V, e, g, prior_weight, len(z)), rho=rho)


def _outline_rows(outline, M: np.ndarray, const: np.ndarray, z: np.ndarray, view: View, guess: np.ndarray,
                  point_indices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The outline's (or the hubs') pseudo-observations as rows of the centred solve: each
    matched point's projection along its normal, less the marks' mean projection (the image
    offset is the marks'), as a linear function L·shape + c (scale 1) of the (840,) shape
    vector, and its target n·(edge − the marks' mean), px. A point's ``weights`` are (n, 280),
    or (n, 280, 3) for a point whose coordinates come from different control points (a hub).

    Args:
        M, const: the marks' camera rows (:func:`camera_rows`); z: (k, 2) their pixels.
        guess: (840,) the shape a pinhole camera is linearised at.
    """
    grad, offset = point_camera(outline.points(guess), view)  # (n, 2, 3), (n, 2)
    n = outline.normals
    along = np.einsum("na,nac->nc", n, grad) * outline.mirror  # (n, 3): d(n·uv)/d(control point)
    weights = outline.weights if outline.weights.ndim == 3 else outline.weights[:, :, None]
    L = (weights * along[:, None, :]).reshape(len(n), -1)
    marks_mean = np.stack([M[0::2].mean(axis=0), M[1::2].mean(axis=0)])  # (2, 35, 3)
    centre = np.einsum("na,akc->nkc", n, marks_mean)
    rows = L.reshape(len(n), -1, 3)
    rows[:, point_indices] -= centre  # (each keypoint is its own control point)
    c = np.einsum("na,na->n", n, offset) - n @ np.array([const[0::2].mean(), const[1::2].mean()])
    target = np.einsum("na,na->n", n, outline.targets - z.mean(axis=0))
    return rows.reshape(len(n), -1), c, target


def _leverage(ABV: np.ndarray, e: np.ndarray, g: float, lam: float, k: int) -> np.ndarray:
    """(k, 2, 2) the diagonal blocks of the solve's hat matrix (how much of each mark's own
    (u, v) its fit follows), at the scale g: the shape's part g²·ABV·diag(1/(g²e + λ))·ABVᵀ
    (the ridge solve's smoother in the singular basis) plus the offset's 1/k per axis."""
    blocks = ABV.reshape(k, 2, -1)
    hat = np.einsum("kar,r,kbr->kab", blocks, g * g / (g * g * e + lam), blocks)
    return hat + np.eye(2) / k


def keypoint_covariance(posterior: ShapePosterior) -> np.ndarray:
    """(35, 3, 3) float: the posterior covariance of each keypoint, normalised units².

    Keypoints the view does not see keep the library's spread; those it sees are pinned by the
    marks (to λ's noise) except along the camera's line of sight. The image scale's own
    uncertainty joins it (:func:`scale_spread`), and a refined view's (``view_spread``); the
    photo-matching deformation that follows does not. docs/fit_accuracy.md measures how it compares
    with the leave-one-out errors.
    """
    cov = joint_keypoint_covariance(posterior)
    n = len(cov) // 3
    return cov.reshape(n, 3, n, 3)[np.arange(n), :, np.arange(n), :]


def coefficient_covariance_times(posterior: ShapePosterior, w: np.ndarray) -> np.ndarray:
    """Σ·``w`` ((q,) or (q, k)): the shape coefficients' posterior covariance (the class
    docstring's Σ, the centres' spread about their mean added; before ``inflation``) times w."""
    shrink = posterior.g ** 2 * posterior.e / (posterior.lam + posterior.g ** 2 * posterior.e)
    shrink = shrink.reshape(-1, *([1] * (np.ndim(w) - 1)))
    out = w - posterior.V @ (shrink * (posterior.V.T @ w))
    spread = posterior.centres - posterior.weights @ posterior.centres
    return out + (spread * posterior.weights[:, None]).T @ (spread @ w)


def joint_keypoint_covariance(posterior: ShapePosterior) -> np.ndarray:
    """(3·35, 3·35) float: the posterior covariance of all the keypoints' coordinates together
    (x1, y1, z1, x2, …), normalised units²: what :func:`keypoint_covariance` gives per keypoint,
    with the keypoints' covariances with each other (a length's spread is that of a difference)."""
    Bk = posterior.keypoint_basis
    cov = Bk @ coefficient_covariance_times(posterior, Bk.T)
    if posterior.scale_solve is not None:
        move = scale_spread(posterior)
        cov += np.outer(move, move)
    cov *= posterior.inflation
    if posterior.view_spread is not None:  # already at the marks' own noise level
        cov += posterior.view_spread.T @ posterior.view_spread
    return cov


#: The step in log image scale of :func:`scale_spread`'s central differences, and the most its
#: standard deviation is taken to be (a flat evidence: the marks say nothing of the scale).
SCALE_STEP, MAX_SCALE_SD = 0.02, 0.5


def scale_trade(posterior: ShapePosterior) -> tuple[np.ndarray, float]:
    """((q,) the posterior mean shape's coefficients' move per unit of log image scale, the log
    scale's standard deviation): a Laplace approximation, like
    :func:`carbody.fit.search.view_spread` for the view.

    The posterior's covariance holds the scale at its best value. But a bigger car farther
    away looks the same: in a level front view the marks pin the width and height in pixels,
    and how many wheelbases they are rests on the scale, which only the library's shapes
    decide. The evidence's curvature in log scale (the shape solved afresh at each scale, every
    prior centre at its own, all moved by one factor) gives that scale's standard deviation at
    the prior's noise level λ; central differences of the posterior mean shape give its slope."""
    if posterior._trade is None:
        pieces, V = posterior.scale_solve, posterior.V
        ABV = pieces.AB @ V
        evidence, means = [], []
        for step in (-SCALE_STEP, 0.0, SCALE_STEP):
            cv, _, nle = _at_scales(pieces.scales * np.exp(step), pieces.ams, ABV, pieces.b, posterior.e,
                                    posterior.lam)
            w = np.exp(-(nle - nle.min()))
            evidence.append(float(nle.min() - np.log(w.sum())))
            means.append((w / w.sum()) @ (pieces.centres + cv @ V.T))
        curvature = (evidence[0] + evidence[2] - 2.0 * evidence[1]) / SCALE_STEP ** 2
        sd = MAX_SCALE_SD if not curvature > 0 else min(1.0 / np.sqrt(curvature), MAX_SCALE_SD)
        posterior._trade = ((means[2] - means[0]) / (2 * SCALE_STEP), float(sd))
    return posterior._trade


def scale_spread(posterior: ShapePosterior) -> np.ndarray:
    """(3·35,): the keypoints' move (normalised units) per one standard deviation of the image's
    scale (:func:`scale_trade`), at λ's noise level."""
    slope, sd = scale_trade(posterior)
    return posterior.keypoint_basis @ slope * sd


def along_scale(solution: MixSolution, log_scale: float, slots: list[KeypointSlot], uv: np.ndarray,
                view: View, point_indices: np.ndarray) -> MixSolution:
    """The solution moved along its trade with the image scale (:func:`scale_trade`): the image
    scale times exp(``log_scale``), the shape moved as the solve would have moved it there, the
    offset and residuals refitted to the marks (``slots``, ``uv``) at ``view``. The marks see
    the move only to second order: it is what they cannot tell."""
    slope, _ = scale_trade(solution.posterior)
    shape = solution.shape + solution.posterior.scale_solve.basis @ slope * log_scale
    return _refitted(solution, shape, solution.scale * float(np.exp(log_scale)), slots, uv, view, point_indices)


def _refitted(solution: MixSolution, shape: np.ndarray, scale: float, slots: list[KeypointSlot], uv: np.ndarray,
              view: View, point_indices: np.ndarray) -> MixSolution:
    """The solution with a moved ``shape`` (840,) at image ``scale``, its offset and residuals
    refitted to the marks (``slots``, ``uv``) at ``view``."""
    from dataclasses import replace

    kp = shape.reshape(-1, 3)[point_indices]
    M, const = camera_rows(slots, view, kp)
    z = np.asarray(uv, dtype=float)
    offset, pred = _image_fit(M, kp, z, scale, const)
    return replace(solution, shape=shape, scale=scale, offset=offset, residual_px=np.linalg.norm(pred - z, axis=1))


def along_keypoints(solution: MixSolution, rows: np.ndarray, step: float, variance: float,
                    slots: list[KeypointSlot], uv: np.ndarray, view: View, point_indices: np.ndarray) -> MixSolution:
    """The solution with the mean of f = ``rows`` (3·35,) · its keypoints moved by ``step``, f's
    variance being ``variance`` (the fit's own and whatever else f's reading carries): the shape
    moved as its posterior regresses it on f, by Cov(shape, f) · ``step`` / ``variance``. Where
    the marks pin f, Cov(shape, f) is small and so is the move; where they do not, the move is
    the prior's own. The offset and residuals are refitted to the marks (``slots``, ``uv``) at
    ``view``."""
    post = solution.posterior
    cov_w = coefficient_covariance_times(post, post.keypoint_basis.T @ np.asarray(rows, dtype=float))
    shape = solution.shape + post.scale_solve.basis @ cov_w * (post.inflation * step / variance)
    return _refitted(solution, shape, solution.scale, slots, uv, view, point_indices)


_SCALE_GRID = np.geomspace(0.1, 10.0, 21)  # the scale search's first grid, × the unregularised scale
_SCALE_STEPS = np.linspace(0.0, 1.0, 17)  # … and each narrowing pass's, across the best bracket


def _map_coefficients(ams: np.ndarray, AB: np.ndarray, b: np.ndarray, lam: float) -> tuple:
    """argmin over a, g > 0 of ‖g·(am + AB·a) − b‖² + λ‖a‖² (the MAP shape and scale), for one or
    several prior centres at once.

    For a fixed scale g the shape coefficients are a ridge solve, done for every g at once in
    the right singular basis of AB (shared by all centres); the scale is then a 1-D minimisation
    (a log grid, then finer grids in the best bracket), vectorised over the centres.
    Args:
        ams: (T, m) the centres' centred projections (the mean shape's, or one per template);
            AB: (m, q) the basis'; b: (m,) the image.
    Returns:
        (a (T, q), g (T,), the minimised costs (T,), −log evidence (T,), (V, e) the right
        singular vectors and squared singular values of AB). With noise variance λ
        (the prior on a is N(0, I)), −log p(b) = cost/(2λ) + ½·log det(I + g²·ABᵀAB/λ) + const:
        the log-det term charges a view for every shape direction it lets the data move, so
        comparing views by it does not favour views where the shape can absorb a wrong camera.
    """
    ams = np.atleast_2d(ams)
    # Thin SVD: directions of a the image cannot see (AB·v = 0) stay at the prior mean, 0.
    if AB.shape[1] > AB.shape[0]:  # more directions than image rows: from the small Gram matrix
        e, U = np.linalg.eigh(AB @ AB.T)
        seen = e > 1e-12 * max(float(e[-1]), 1e-300)
        e, U = e[seen][::-1], U[:, seen][:, ::-1]
        V = (AB.T @ U) / np.sqrt(e)
    else:
        _, sv, Vt = np.linalg.svd(AB, full_matrices=False)
        V, e = Vt.T, sv**2
    ABV = AB @ V
    y1, y2 = ABV.T @ b, ams @ ABV  # (q,), (T, q)

    def coeffs(g):  # g: (T, n) -> (T, n, q): g·(y1 − g·y2) / (g²·e + λ)
        g = g[..., None]
        c = g * y2[:, None]
        np.subtract(y1, c, out=c)
        c *= g
        d = g * g * e
        d += lam
        c /= d
        return c

    # ABV's columns are orthogonal with squared norms e, so the cost needs only q-vectors:
    # ‖g·(am + ABV·c) − b‖² + λ‖c‖² = g²·am·am − 2g·am·b + b·b − Σ_q N_q²/D_q at the optimal c,
    # with N = g·(y1 − g·y2) and D = g²·e + λ (c = N/D: the cross terms sum to −2N²/D, the
    # quadratic ones to N²/D).
    amam, amb, bb = np.einsum("tm,tm->t", ams, ams)[:, None], (ams @ b)[:, None], float(b @ b)

    def cost(g):  # (T, n), in place on one (T, n, q) array (the search's bulk)
        gq = g[..., None]
        r = gq * y2[:, None]
        np.subtract(y1, r, out=r)
        r *= r
        d = (gq * gq) * e
        d += lam
        r /= d
        return g * (g * amam - 2.0 * amb) + bb - (g * g) * r.sum(axis=2)

    # The unregularised scale of each centre brackets the answer.
    g0 = np.maximum(amb[:, 0] / np.maximum(amam[:, 0], 1e-300), 1e-6)
    grid = g0[:, None] * _SCALE_GRID
    i = np.argmin(cost(grid), axis=1)
    rows = np.arange(len(ams))
    lo, hi = grid[rows, np.maximum(i - 1, 0)], grid[rows, np.minimum(i + 1, grid.shape[1] - 1)]
    for _ in range(SCALE_PASSES):  # each pass narrows the bracket 8×, all centres at once
        grid = lo[:, None] + (hi - lo)[:, None] * _SCALE_STEPS
        costs = cost(grid)
        i = np.clip(np.argmin(costs, axis=1), 1, 15)
        lo, hi = grid[rows, i - 1], grid[rows, i + 1]
    # The vertex of the parabola through the best three of the last pass (equally spaced by h).
    c0, c1, c2 = costs[rows, i - 1], costs[rows, i], costs[rows, i + 1]
    h, curvature = (hi - lo) / 2.0, c0 - 2.0 * c1 + c2
    shift = np.where(curvature > 0, 0.5 * (c0 - c2) / np.where(curvature > 0, curvature, 1.0), 0.0)
    g = grid[rows, i] + np.clip(shift, -1.0, 1.0) * h
    cv, c, nle = _at_scales(g, ams, ABV, b, e, lam)
    return cv @ V.T, g, c, nle, (V, e)


def _at_scales(g: np.ndarray, ams: np.ndarray, ABV: np.ndarray, b: np.ndarray, e: np.ndarray,
               lam: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(coefficients (T, q) in the singular basis, costs (T,), −log evidence (T,)) of each
    centre's MAP shape at its image scale ``g`` (T,) (:func:`_map_coefficients`' notation)."""
    gq = g[:, None]
    cv = gq * (ABV.T @ b - gq * (ams @ ABV)) / (gq * gq * e + lam)
    r = gq * (ams + cv @ ABV.T) - b
    c = np.einsum("tm,tm->t", r, r) + lam * np.einsum("tq,tq->t", cv, cv)
    return cv, c, c / (2 * lam) + 0.5 * np.sum(np.log1p(gq ** 2 * e / lam), axis=1)


def _solve_working_set(basis: KeypointBasis, rows: np.ndarray, const: np.ndarray, b: np.ndarray,
                       warm: np.ndarray | None, slots: list[KeypointSlot], M: np.ndarray,
                       full_set_max: int = FULL_SET_MAX, growth: int = WORKING_SET_GROWTH) -> np.ndarray:
    """NNLS over all models of ``basis`` with A = rows·X + const·1ᵀ (X the (105, N) keypoint
    rows), A never built whole for a large library.

    Args:
        rows: (2k, 105) float, the centred projection rows (divided by the basis size).
        const: (2k,) float, the centred constant of a pinhole camera's rows (divided likewise;
            zeros for an orthographic one): a model's image is rows·X_j + const, and with
            G = s·H summing to s the constant enters every column.
        b: (2k,) float, the centred, scaled image keypoints.
        M: (2k, 35, 3) float, the camera rows (:func:`camera_rows`).
    Returns:
        (N,) float, G ≥ 0.
    """
    n = basis.n_models
    flat = basis.X.reshape(-1, n)
    # Each image coordinate reads three coordinates of one keypoint: gather those, not all 105.
    kp = np.array([s.keypoint_id - 1 for s in slots])
    at = np.arange(len(slots))
    coef = np.stack([M[0::2][at, kp], M[1::2][at, kp]], axis=1) / basis.size  # (k, 2, 3)

    def columns(idx: np.ndarray | None) -> np.ndarray:
        Xs = basis.X[kp] if idx is None else basis.X[:, :, idx][kp]
        A = np.einsum("kac,kcn->kan", coef, Xs, dtype=np.float64, optimize=False)
        A -= A.mean(axis=0)  # centring per image axis
        A = A.reshape(2 * len(kp), -1)
        A += const[:, None]
        return A

    if n <= full_set_max:
        return nnls_active_set(columns(None), b, passive=warm)

    def gradient(r: np.ndarray) -> np.ndarray:
        """Aᵀ·r over every model: one pass over the (105, N) keypoint rows."""
        return ((rows.T @ r).astype(flat.dtype) @ flat).astype(np.float64) + const @ r

    g0 = gradient(-b)
    seed = np.argsort(g0)[:growth]
    stride = np.arange(0, n, max(1, n // STRIDE_SAMPLE))
    W = np.unique(np.concatenate([seed, stride] + ([np.asarray(warm)] if warm is not None else [])))
    G = np.zeros(n)
    tol = 1e-9 * max(float(np.max(np.abs(g0))), 1e-300)
    for _ in range(50):
        A = columns(W)
        gw = nnls_active_set(A, b, passive=np.flatnonzero(G[W] > 0) if G.any() else None)
        G[:] = 0.0
        G[W] = gw
        g = gradient(A @ gw - b)
        g[W] = np.inf
        viol = np.flatnonzero(g < -tol)
        if not len(viol):
            break
        add = viol[np.argsort(g[viol])[:growth]]
        W = np.unique(np.concatenate([W, add]))
    return G
