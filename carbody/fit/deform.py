"""Photo-matching deformation: move the fitted model onto the annotated keypoints.

The library mix is the most likely car within the library's span; a real car is never exactly in
it, so the mix's keypoints land a few pixels off the marks (tens of pixels for a car unlike every
template). This stage adds a smooth displacement field d(p) to the mix: a Gaussian process with a
squared-exponential kernel (``FIELD_SIGMA``, ``FIELD_LENGTH``) that is mirror-symmetric (its lateral
component vanishes on the symmetry plane, so the two halves still meet) and pinned at the wheel
centres (the car frame and the wheelbase stay exact). Its posterior mean given the keypoint
residuals moves every control point of the wireframe, so curves stay smooth and joined.

A residual seen in one image says nothing about depth: the field moves points only across the
view, and what the photo cannot see stays as the prior put it. Measured on the leave-one-out
benchmark (BENCHMARKS.md) it lowers the mean 3D error by ~2 mm and the reprojection residual from
2.7 to 2.0 px (1 px noise); it is on by default for the Gaussian-prior methods and off for the
paper's solve, which stays as published.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carbody.camera import View
from carbody.fit.keypoints_io import KeypointSlot
from carbody.topology import Topology

#: Standard deviation of each displacement component, normalised units (≈ 27 mm at a 2.7 m
#: wheelbase): how far a real car strays from the library's span, locally.
FIELD_SIGMA = 10.0

#: Correlation length of the field, normalised units (≈ 1.1 m at a 2.7 m wheelbase): a
#: keypoint's correction carries to the curves around it, not across the car.
FIELD_LENGTH = 400.0

#: Keypoint placement noise, normalised units (≈ 2 px when the car spans 900 px).
KEYPOINT_NOISE = 3.5

#: Fraction of the field's variance its low-rank basis keeps.
FIELD_ENERGY = 0.9999


@dataclass
class DeformationField:
    """The displacement field's prior as a basis: d = basis·a with a ~ N(0, I).

    Attributes:
        basis: (3·P, q) float, normalised units, rows ordered like a shape vector (x, y, z of
            each of the P control points).
    """

    basis: np.ndarray

    @classmethod
    def around(cls, reference: np.ndarray, topology: Topology, sigma: float = FIELD_SIGMA,
               length: float = FIELD_LENGTH) -> "DeformationField":
        """The field's prior around a reference model.

        Args:
            reference: (P, 3) float, normalised control points (the library mean) where the
                kernel is evaluated.
        """
        P = np.asarray(reference, dtype=float).reshape(-1, 3)
        mirrored = P * [-1.0, 1.0, 1.0]
        two_l2 = 2.0 * length * length
        near = np.exp(-np.sum((P[:, None] - P[None]) ** 2, axis=-1) / two_l2)
        across = np.exp(-np.sum((P[:, None] - mirrored[None]) ** 2, axis=-1) / two_l2)
        n = len(P)
        cov = np.zeros((3 * n, 3 * n))
        # d(p) and the mirror's d(Mp) = M·d(p) are one field: lateral parts subtract, others add.
        for c, sign in ((0, -1.0), (1, 1.0), (2, 1.0)):
            cov[c::3, c::3] = sigma * sigma * (near + sign * across)
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
        return cls(basis=evecs[:, :q] * np.sqrt(evals[:q]))

    def fit_to_keypoints(self, shape: np.ndarray, point_indices: np.ndarray,
                         slots: list[KeypointSlot], uv: np.ndarray, view: View, scale: float,
                         offset: np.ndarray, noise: float = KEYPOINT_NOISE) -> np.ndarray:
        """The shape moved by the field's posterior mean given the keypoint residuals.

        Args:
            shape: (3·P,) float, the fitted model, normalised units.
            point_indices: (35,) int, control point of each keypoint.
            slots, uv: the annotated keypoints and their (k, 2) pixels.
            view, scale, offset: the fitted camera (pixels per normalised unit; (2,) pixels).
            noise: keypoint placement noise, normalised units.
        Returns:
            (3·P,) float, the deformed shape.
        """
        from carbody.fit.solve import camera_rows

        keypoints = shape.reshape(-1, 3)[point_indices]
        rows, const = camera_rows(slots, view, keypoints)  # (2k, 35, 3), (2k,)
        at_keypoints = self.basis.reshape(-1, 3, self.basis.shape[1])[point_indices]
        A = scale * np.einsum("rkc,kcq->rq", rows, at_keypoints)
        predicted = offset + scale * (np.einsum("rkc,kc->r", rows, keypoints) + const).reshape(-1, 2)
        r = (np.asarray(uv, dtype=float) - predicted).ravel()
        gram = A @ A.T + (noise * scale) ** 2 * np.eye(len(r))
        a = A.T @ np.linalg.solve(gram, r)
        return shape + self.basis @ a
