"""A car wireframe: the 280 control points of the left half's 70 cubic Bezier curves.

Templates, library models and fitted cars are all wireframes. This module reads and writes them
as STEP (through :mod:`carbody.occ.step_curves`) and refuses files that do not carry exactly the
topology's curves: a missing, extra, misnamed or non-cubic curve, or curves that no longer meet
at their junctions, is one :class:`~carbody.errors.TemplateError` naming the file and the curve.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.errors import TemplateError
from carbody.tolerances import CUBIC_TOL_MM, JUNCTION_TOL_MM
from carbody.topology import POINTS_PER_CURVE, Topology, load_topology

#: Suffix of a right-half curve's name in a STEP file holding both halves.
RIGHT_SUFFIX = "_right"

#: Reflection of the car frame in its symmetry plane x = 0.
MIRROR = np.array([-1.0, 1.0, 1.0])


@dataclass
class Wireframe:
    """The left half of a car wireframe.

    Attributes:
        name: the car (STEP product name).
        control_points: (280, 3) float, mm, car frame; curve i owns rows 4i..4i+3.
    """

    name: str
    control_points: np.ndarray

    def __post_init__(self) -> None:
        self.control_points = np.asarray(self.control_points, dtype=float)
        n = load_topology().n_points
        if self.control_points.shape != (n, 3):
            raise TemplateError(f"{self.name}: a wireframe has {n} x 3 control points, "
                                f"got {self.control_points.shape}")

    def curve_points(self, index: int) -> np.ndarray:
        """(4, 3) control points of curve ``index``."""
        return self.control_points[POINTS_PER_CURVE * index:POINTS_PER_CURVE * (index + 1)]

    def keypoints(self, topology: Topology | None = None) -> dict[str, list[float]]:
        """{keypoint name: [x, y, z] mm} of the left half's 35 keypoints."""
        topo = topology or load_topology()
        pts = self.control_points[topo.keypoint_point_indices]
        return {k.name: [float(v) for v in p] for k, p in zip(topo.keypoints, pts)}

    def named_curves(self, both_halves: bool = False) -> list[tuple[str, np.ndarray]]:
        """(name, (4, 3) poles) per curve; with ``both_halves`` the mirror half follows,
        curves on the symmetry plane once."""
        topo = load_topology()
        out = [(c.name, self.curve_points(c.index)) for c in topo.curves]
        if both_halves:
            for c in topo.curves:
                if not (c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions):
                    out.append((c.name + RIGHT_SUFFIX, self.curve_points(c.index) * MIRROR))
        return out

    def measure(self, samples: int = 200) -> dict[str, float]:
        """Overall length, width (both halves), height above the wheel-centre line, wheelbase; mm."""
        topo = load_topology()
        pts = sample_curves(self.control_points, samples).reshape(-1, 3)
        front, rear = (wheel_centre(self.control_points, topo, side) for side in ("front", "rear"))
        return {
            "length_mm": float(np.ptp(pts[:, 1])),
            "width_mm": float(2 * pts[:, 0].max()),
            "top_z_mm": float(pts[:, 2].max()),
            "wheelbase_mm": float(np.hypot(*(rear - front))),
        }


def sample_curves(control_points: np.ndarray, samples: int = 24) -> np.ndarray:
    """Points along every cubic Bezier curve.

    Args:
        control_points: (4k, 3) float, k curves in rows of four.
        samples: points per curve.
    Returns:
        (k, samples, 3) float.
    """
    cp = control_points.reshape(-1, POINTS_PER_CURVE, 3)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    basis = np.hstack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3])  # (samples, 4)
    return np.einsum("sk,ckd->csd", basis, cp)


def wheel_centre(control_points: np.ndarray, topology: Topology, side: str) -> np.ndarray:
    """(y, z) of the front or rear wheel centre: midpoint of the arch's two points level with it."""
    a, b = (topology.junction_point_index(j) for j in topology.wheel_centres[side])
    return (control_points[a, 1:] + control_points[b, 1:]) / 2


def write_wireframe(path: str | Path, wireframe: Wireframe, both_halves: bool = False) -> Path:
    """Write ``wireframe`` as STEP: one named cubic Bezier edge per curve, mm, product = car."""
    from carbody.occ.step_curves import write_curves_step

    return write_curves_step(path, wireframe.named_curves(both_halves), wireframe.name)


def read_wireframe(path: str | Path, topology: Topology | None = None) -> Wireframe:
    """Read a wireframe STEP file written by carbody or saved back by another CAD system.

    Right-half curves (``*_right``) of a two-half file are ignored; the left half is the model.
    A curve stored the other way round is turned back to the topology's direction.

    Raises:
        TemplateError: unreadable file; a missing, extra, duplicated or non-cubic curve; curves
            that do not meet at their shared junction.
    """
    from carbody.occ.step_curves import read_curves_step

    topo = topology or load_topology()
    path = Path(path)
    product, curves = read_curves_step(path)
    wanted = {c.name for c in topo.curves}
    found: dict[str, np.ndarray] = {}
    for c in curves:
        if c.name.endswith(RIGHT_SUFFIX) and c.name[: -len(RIGHT_SUFFIX)] in wanted:
            continue
        if not c.name:
            raise TemplateError(f"{path}: holds a curve with no name (every curve must carry its topology name)")
        if c.name not in wanted:
            raise TemplateError(f"{path}: unknown curve {c.name!r} (not in the wireframe topology)")
        if c.name in found:
            raise TemplateError(f"{path}: curve {c.name!r} appears twice")
        found[c.name] = _as_cubic_bezier(c, path)
    missing = [c.name for c in topo.curves if c.name not in found]
    if missing:
        raise TemplateError(f"{path}: curve {missing[0]!r} is missing"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    points = np.concatenate([found[c.name] for c in topo.curves])
    points = _orient_curves(points, topo, path)
    return Wireframe(product or path.stem, points)


def _as_cubic_bezier(curve, path: Path) -> np.ndarray:
    """(4, 3) poles of a curve that must be a non-rational cubic Bezier (one span, 4 poles)."""
    poles = curve.poles
    if curve.rational or curve.degree != 3 or curve.spans != 1 or len(poles) != POINTS_PER_CURVE:
        # A cubic stored with extra knots or elevated degree is still accepted when it is one.
        if not curve.rational and len(poles) >= 2:
            from carbody.occ.step_curves import cubic_fit_error

            cubic, err = cubic_fit_error(poles, curve.degree, curve.spans)
            if err <= CUBIC_TOL_MM:
                return cubic
        raise TemplateError(f"{path}: curve {curve.name!r} is not a cubic Bezier "
                            f"(degree {curve.degree}, {len(poles)} poles, {curve.spans} spans"
                            f"{', rational' if curve.rational else ''})")
    return poles


def _orient_curves(points: np.ndarray, topo: Topology, path: Path) -> np.ndarray:
    """Turn round curves stored end-to-start, then check every junction is met by all its curves."""
    pts = points.reshape(-1, POINTS_PER_CURVE, 3).copy()
    ends = {j: [] for j in topo.junctions}
    for c in topo.curves:
        ends[c.start].append(c.index)
        ends[c.end].append(c.index)

    def end_points(i):
        return pts[i, 0], pts[i, -1]

    for c in topo.curves:
        first, last = end_points(c.index)

        def mismatch(p, junction):
            others = [o for o in ends[junction] if o != c.index]
            return sum(min(np.linalg.norm(p - q) for q in end_points(o)) for o in others)

        as_is = mismatch(first, c.start) + mismatch(last, c.end)
        turned = mismatch(last, c.start) + mismatch(first, c.end)
        if turned < as_is:
            pts[c.index] = pts[c.index, ::-1]
    flat = pts.reshape(-1, 3)
    for junction, idx in topo.junction_groups().items():
        spread = np.linalg.norm(flat[idx] - flat[idx].mean(axis=0), axis=1).max()
        if spread > JUNCTION_TOL_MM:
            names = sorted({topo.curves[i // POINTS_PER_CURVE].name for i in idx})
            raise TemplateError(f"{path}: curves {', '.join(names)} do not meet at junction "
                                f"{junction!r} (off by {spread:.3g} mm)")
    return flat
