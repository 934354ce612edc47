"""Photo-matching deformation: move the fitted model onto the annotated keypoints.

The library mix is the most likely car within the library's span; a real car is never exactly in
it, so the mix's keypoints land a few pixels off the marks (tens of pixels for a car unlike every
template). This stage adds a smooth displacement field d(p) to the mix: a Gaussian process,
mirror-symmetric (its lateral component vanishes on the symmetry plane, so the two halves still
meet) and pinned at the wheel centres (the car frame and the wheelbase stay exact). Its
posterior mean given the keypoint residuals moves every control point of the wireframe, so
curves stay smooth and joined. The field is the sum of two squared-exponential parts:

- a broad one (``FIELD_SIGMA``, ``FIELD_LENGTH``, the same in every direction): the car a little
  longer here, taller there;
- a local one (``LOCAL_SIGMA``, ``LOCAL_LENGTH``), mostly along the car: where cars differ
  point by point is where their features sit along the body — a B-pillar, a door cut, the end
  of a window — while the side of the body stays where it is. A mark off the mix by a pillar's
  shift then moves the point along the car, not straight across the picture to the nearest spot
  on its line of sight.

The local part also sits in the shape prior itself, at a fraction of its amplitude and
correlated right across the car (``JOINT_FIELD_AMPLITUDE`` in :mod:`carbody.fit.shape_prior`,
:func:`joint_field_basis`), solved with the mix: a feature off every template along the car is
then taken up there already, not by bending the whole mix to reach it (on a near-side view, by
making the car wider). This stage follows what is left.

Both parts move a curve's inner poles with its ends (:func:`carried_by_curve_ends`), and a
junction that only splits a feature line into cubics with the keypoints ending that line
(:func:`carried_by_chain_ends`), so a line passes through its marks without kinking between them.

A residual seen in one image says nothing about depth, so what the photo cannot see stays
mostly as the prior put it. How much of a residual is the car and how much the marking error is
chosen per photo by the field's marginal likelihood (type-II maximum likelihood) over a small
grid: the local part's amplitude (``LOCAL_AMPLITUDES``) and the marks' noise
(``KEYPOINT_NOISE`` × ``NOISE_FACTORS``), so careless marks are not chased. Measured on the
leave-one-out benchmark (docs/fit_accuracy.md, where these constants were chosen); on by default for
the Gaussian-prior methods and off for the paper's solve, which stays as published.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carbody.camera import View
from carbody.fit.keypoints_io import KeypointSlot
from carbody.errors import TopologyError
from carbody.topology import Topology

#: Standard deviation of each displacement component, normalised units (≈ 27 mm at a 2.7 m
#: wheelbase): how far a real car strays from the library's span, locally.
FIELD_SIGMA = 10.0

#: Correlation length of the field, normalised units (≈ 1.1 m at a 2.7 m wheelbase): a
#: keypoint's correction carries to the curves around it, not across the car.
FIELD_LENGTH = 400.0

#: Standard deviation of the local part's (x, y, z) components, normalised units (≈ 14, 108
#: and 27 mm at a 2.7 m wheelbase): features move along the car far more than across it.
LOCAL_SIGMA = (5.0, 40.0, 10.0)

#: Correlation length of the local part, normalised units (≈ 0.32 m at a 2.7 m wheelbase).
LOCAL_LENGTH = 120.0

#: Correlation lengths (x, y, z), normalised units, of the local part where it joins the shape
#: prior (:func:`joint_field_basis`): across the car as long as the car is wide, since a feature
#: whose place along the car differs — a windscreen header, a pillar, a window's end — runs
#: across it, so its hidden centre follows its visible corner; along the car and up as short as
#: the local part's own.
JOINT_LENGTH = (800.0, LOCAL_LENGTH, LOCAL_LENGTH)

#: The local part's amplitudes the marginal likelihood chooses from.
LOCAL_AMPLITUDES = (0.5, 1.0)

#: Keypoint placement noise, normalised units (≈ 2 px when the car spans 900 px): the least the
#: fit assumes …
KEYPOINT_NOISE = 3.5

#: … and the multiples of it the marginal likelihood chooses from (up to ≈ 12 px).
NOISE_FACTORS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0)

#: Fraction of the field's variance its low-rank basis keeps.
FIELD_ENERGY = 0.9999


@dataclass
class DeformationField:
    """The displacement field's prior as two bases: d = basis·a + local·b with a, b ~ N(0, I).

    Attributes:
        basis: (3·P, q) float, the broad part, normalised units, rows ordered like a shape
            vector (x, y, z of each of the P control points).
        local: (3·P, q') float, the local part, same layout.
    """

    basis: np.ndarray
    local: np.ndarray

    @classmethod
    def around(cls, reference: np.ndarray, topology: Topology) -> "DeformationField":
        """The field's prior around a reference model.

        Args:
            reference: (P, 3) float, normalised control points (the library mean) where the
                kernels are evaluated.
        """
        return cls(basis=_field_basis(reference, topology, (FIELD_SIGMA,) * 3, FIELD_LENGTH),
                   local=_field_basis(reference, topology, LOCAL_SIGMA, LOCAL_LENGTH))

    def fit_to_keypoints(self, shape: np.ndarray, point_indices: np.ndarray,
                         slots: list[KeypointSlot], uv: np.ndarray, view: View, scale: float,
                         offset: np.ndarray, noise: float = KEYPOINT_NOISE) -> np.ndarray:
        """The shape moved by the field's posterior mean given the keypoint residuals, with the
        local part's amplitude and the marks' noise of the largest marginal likelihood.

        Args:
            shape: (3·P,) float, the fitted model, normalised units.
            point_indices: (35,) int, control point of each keypoint.
            slots, uv: the annotated keypoints and their (k, 2) pixels.
            view, scale, offset: the fitted camera (pixels per normalised unit; (2,) pixels).
            noise: the least keypoint placement noise, normalised units.
        Returns:
            (3·P,) float, the deformed shape.
        """
        from scipy.linalg import cho_factor, cho_solve

        from carbody.fit.solve import camera_rows

        keypoints = shape.reshape(-1, 3)[point_indices]
        rows, const = camera_rows(slots, view, keypoints)  # (2k, 35, 3), (2k,)

        def seen(basis: np.ndarray) -> np.ndarray:  # the basis' pixels at the marks
            return scale * np.einsum("rkc,kcq->rq", rows, basis.reshape(-1, 3, basis.shape[1])[point_indices])

        A, L = seen(self.basis), seen(self.local)
        predicted = offset + scale * (np.einsum("rkc,kc->r", rows, keypoints) + const).reshape(-1, 2)
        r = (np.asarray(uv, dtype=float) - predicted).ravel()
        broad, local, eye = A @ A.T, L @ L.T, np.eye(len(r))
        best = None
        for amplitude in LOCAL_AMPLITUDES:
            for factor in NOISE_FACTORS:
                K = broad + amplitude ** 2 * local + (factor * noise * scale) ** 2 * eye
                chol = cho_factor(K, lower=True)  # (one factorisation: the solve and the determinant)
                alpha = cho_solve(chol, r)
                # −log marginal likelihood of the residuals, up to a constant
                nll = 0.5 * r @ alpha + np.sum(np.log(np.diag(chol[0])))
                if best is None or nll < best[0]:
                    best = (nll, amplitude, alpha)
        _, amplitude, alpha = best
        return shape + self.basis @ (A.T @ alpha) + amplitude ** 2 * (self.local @ (L.T @ alpha))


def joint_field_basis(reference: np.ndarray, topology: Topology) -> np.ndarray:
    """(3·P, q) the local part's basis as it joins the shape prior: ``LOCAL_SIGMA``, correlated
    over ``JOINT_LENGTH`` (see :data:`carbody.fit.shape_prior.JOINT_FIELD_AMPLITUDE`)."""
    return _field_basis(reference, topology, LOCAL_SIGMA, JOINT_LENGTH)


def _field_basis(reference: np.ndarray, topology: Topology, sigma: tuple[float, float, float],
                 length: float | tuple[float, float, float]) -> np.ndarray:
    """(3·P, q): a low-rank basis of a mirror-symmetric squared-exponential displacement field
    with per-axis standard deviations ``sigma`` and correlation ``length`` (one, or per axis of
    the distance: x, y, z), pinned at the wheel centres."""
    P = np.asarray(reference, dtype=float).reshape(-1, 3) / np.asarray(length, dtype=float)
    mirrored = P * [-1.0, 1.0, 1.0]
    near = np.exp(-np.sum((P[:, None] - P[None]) ** 2, axis=-1) / 2.0)
    across = np.exp(-np.sum((P[:, None] - mirrored[None]) ** 2, axis=-1) / 2.0)
    n = len(P)
    cov = np.zeros((3 * n, 3 * n))
    # d(p) and the mirror's d(Mp) = M·d(p) are one field: lateral parts subtract, others add.
    for c, sign in ((0, -1.0), (1, 1.0), (2, 1.0)):
        cov[c::3, c::3] = sigma[c] * sigma[c] * (near + sign * across)
    # Pin the wheel centres' (y, z): condition the process on zero displacement there.
    pins = []
    for side in ("front", "rear"):
        a, b = (topology.junction_point_index(j) for j in topology.wheel_centres[side])
        for c in (1, 2):
            row = np.zeros(3 * n)
            row[3 * a + c] += 0.5
            row[3 * b + c] += 0.5
            pins.append(row)
    A = np.array(pins)
    CA = cov @ A.T
    cov -= CA @ np.linalg.solve(A @ CA, CA.T)
    evals, evecs = np.linalg.eigh(cov)
    evals, evecs = np.clip(evals[::-1], 0.0, None), evecs[:, ::-1]
    q = int(np.searchsorted(np.cumsum(evals) / evals.sum(), FIELD_ENERGY)) + 1
    return carried_by_curve_ends(carried_by_chain_ends(evecs[:, :q] * np.sqrt(evals[:q]), reference, topology))


def chain_weights(reference: np.ndarray, topology: Topology) -> dict[str, tuple[str, str, float]]:
    """{junction that is no keypoint: (keypoint A, keypoint B, f)}: the junction lies on the run
    of curves from keypoint A to keypoint B (a fender top, a roof side, a centre line), at the
    fraction f of that run's length (chords between its junctions on ``reference``)."""
    keypoints = {k.name for k in topology.keypoints}
    at = {j: np.asarray(reference, float).reshape(-1, 3)[topology.junction_point_index(j)]
          for j in topology.junctions}
    neighbours: dict[str, list[str]] = {j: [] for j in topology.junctions}
    for c in topology.curves:
        neighbours[c.start].append(c.end)
        neighbours[c.end].append(c.start)
    lone = [j for j in topology.junctions if j not in keypoints and len(neighbours[j]) != 2]
    if lone:  # (the runs below walk through such junctions: each must join exactly two curves)
        raise TopologyError(f"junction {lone[0]} is no keypoint but ends or branches a run of curves")
    out = {}
    for j in topology.junctions:
        if j in keypoints:
            continue
        ends, lengths = [], []
        for first in neighbours[j]:  # walk each way to the keypoint that ends the run
            prev, cur, length = j, first, float(np.linalg.norm(at[first] - at[j]))
            while cur not in keypoints:
                nxt = next(n for n in neighbours[cur] if n != prev)
                prev, cur, length = cur, nxt, length + float(np.linalg.norm(at[nxt] - at[cur]))
            ends.append(cur)
            lengths.append(length)
        out[j] = (ends[0], ends[1], lengths[0] / (lengths[0] + lengths[1]))
    return out


def carried_by_chain_ends(basis: np.ndarray, reference: np.ndarray, topology: Topology) -> np.ndarray:
    """A displacement basis (3·P, q) whose junctions that are no keypoints move as the blend of
    the keypoints ending their run of curves, by where along the run they lie
    (:func:`chain_weights`).

    Such a junction only splits a feature line (a fender top, a roof side, a centre line) into
    cubics: it is no feature of its own that a car could have elsewhere. A kernel over the
    distance moves it by its distance from the marks, so a mark moved further than the local
    part's correlation length from the mix (an A-pillar foot higher than every template's)
    leaves the split points of the line behind, and the line kinks between two marks it passes
    through: the fitted fender top sagged 20–100 mm below its ends on the real photos, its
    hood drawn low in the photo. Blended from the run's ends, the line follows both. The
    keypoints' own rows are unchanged, so what the marks see of the field is too.
    """
    out, groups = basis.copy(), topology.junction_groups()

    def rows(junction: str) -> np.ndarray:
        i = topology.junction_point_index(junction)
        return basis[3 * i:3 * i + 3]
    for j, (a, b, f) in chain_weights(reference, topology).items():
        moved = (1.0 - f) * rows(a) + f * rows(b)
        for index in groups[j]:
            out[3 * index:3 * index + 3] = moved
    return out


def carried_by_curve_ends(basis: np.ndarray) -> np.ndarray:
    """A displacement basis (3·P, q) whose inner poles move with their curve's end: each cubic's
    second pole as its first, its third as its fourth.

    The field is smooth, but two curves leaving a junction along one line (a cusp: the sill and
    the wheel arch at the arch's foot) or at an acute angle (a belt line and a door edge) have
    their poles near the junction a few centimetres apart, where a smooth field still moves
    them differently; tilted by a few degrees the two curves cross, and the region between them
    cannot be surfaced. Moved with their ends, the curves keep the mix's end tangents (every
    library model's directions there) and their junctions meet as they did; the keypoints are
    junctions, so what the marks see of the field is unchanged.
    """
    rows = np.arange(basis.shape[0]).reshape(-1, 4, 3)  # (curve, pole, xyz) -> row
    out = basis.copy()
    out[rows[:, 1]] = basis[rows[:, 0]]
    out[rows[:, 2]] = basis[rows[:, 3]]
    return out
