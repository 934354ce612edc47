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

    # ---- editing: the Python twin of moving poles in FreeCAD (workbench/carbody_wb/model.py)

    def with_curve_poles(self, curve: str, poles: np.ndarray) -> "Wireframe":
        """A copy with one curve's poles replaced; the curves meeting it at a junction keep
        meeting it there (their end poles follow), and mirror symmetry is kept (a point on the
        symmetry plane stays at x = 0).

        Args:
            curve: a curve name; a right-half name (``*_right``) edits its left twin mirrored.
            poles: (4, 3) float, mm.
        Raises:
            TemplateError: an unknown curve, or poles of the wrong shape or not numbers.
        """
        topo = load_topology()
        name, mirror = _left_name(curve, topo)
        poles = np.asarray(poles, float)
        if poles.shape != (POINTS_PER_CURVE, 3) or not np.isfinite(poles).all():
            raise TemplateError(f"{self.name}: curve {curve!r} needs {POINTS_PER_CURVE} x 3 poles (mm), "
                                f"got {poles.shape}")
        c = topo.curve(name)
        cp = self.control_points.copy()
        cp[POINTS_PER_CURVE * c.index:POINTS_PER_CURVE * (c.index + 1)] = poles * MIRROR if mirror else poles
        for junction, row in ((c.start, 0), (c.end, POINTS_PER_CURVE - 1)):
            cp[topo.junction_groups()[junction]] = cp[POINTS_PER_CURVE * c.index + row]
        return Wireframe(self.name, _on_symmetry_plane(cp, topo))

    def with_junction_moved(self, junction: str, delta_mm, handles: bool = True) -> "Wireframe":
        """A copy with one junction moved by ``delta_mm`` (3,), mm, as a node of a Bezier path
        moves: every curve's end pole on it and, with ``handles``, the pole next to it, so the
        curves leave the junction in the directions they did (without, only the end poles
        move). A right-half name (``*_right``) moves the left twin mirrored; a junction on the
        symmetry plane moves in y and z only."""
        topo = load_topology()
        name, mirror = _left_junction(junction, topo)
        delta = np.asarray(delta_mm, float) * (MIRROR if mirror else 1.0)
        cp = self.control_points.copy()
        ends = np.asarray(topo.junction_groups()[name])
        cp[ends] += delta
        if handles:  # the pole beside each end pole: row 1 of a start, row 2 of an end
            cp[np.where(ends % POINTS_PER_CURVE == 0, ends + 1, ends - 1)] += delta
        return Wireframe(self.name, _on_symmetry_plane(cp, topo))

    def with_curves_moved(self, curves, delta_mm) -> "Wireframe":
        """A copy with every pole of the named curves moved by ``delta_mm`` (3,), mm, and the
        other curves' ends on their junctions with them: raising a roof line raises the roof's
        curves and stretches the pillars up to it. Right-half names move their left twins
        mirrored; points on the symmetry plane move in y and z only."""
        topo = load_topology()
        cp = self.control_points.copy()
        delta = np.asarray(delta_mm, float)
        moved_junctions: dict[str, np.ndarray] = {}
        for curve in curves:
            name, mirror = _left_name(curve, topo)
            c = topo.curve(name)
            d = delta * (MIRROR if mirror else 1.0)
            cp[POINTS_PER_CURVE * c.index:POINTS_PER_CURVE * (c.index + 1)] = self.curve_points(c.index) + d
            moved_junctions[c.start] = moved_junctions[c.end] = d
        groups = topo.junction_groups()
        for junction, d in moved_junctions.items():
            cp[groups[junction]] = self.control_points[groups[junction]] + d
        return Wireframe(self.name, _on_symmetry_plane(cp, topo))


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
    """Read a wireframe: a STEP file written by carbody or saved back by another CAD system
    (FreeCAD, CadQuery, build123d: see :func:`carbody.occ.step_curves.read_curves_step`), or a
    wireframe JSON file (:func:`write_wireframe_json`).

    Right-half curves (``*_right``) of a two-half file are ignored; the left half is the model.
    A curve stored the other way round is turned back to the topology's direction.

    Raises:
        TemplateError: unreadable file; a missing, extra, duplicated or non-cubic curve; curves
            that do not meet at their shared junction.
    """
    path = Path(path)
    product, curves = read_named_curves(path)
    return wireframe_from_curves(curves, product or path.stem, str(path), topology)


def read_named_curves(path: str | Path):
    """(product name, [NamedCurve]) of a wireframe STEP or JSON file, as the file names them."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        return _read_json_curves(path)
    from carbody.occ.step_curves import read_curves_step

    return read_curves_step(path)


def wireframe_from_curves(curves, name: str, source: str, topology: Topology | None = None) -> Wireframe:
    """The left-half :class:`Wireframe` of named curves (both halves may be given).

    Args:
        curves: :class:`~carbody.occ.step_curves.NamedCurve` (or objects with ``name``,
            ``poles``, ``degree``, ``spans``, ``rational``), mm.
        name: the car.
        source: what the curves came from, for messages (a file, "the compound").
    Raises:
        TemplateError: a missing, unnamed, unknown, duplicated or non-cubic curve, or curves that
            do not meet at a junction; one line naming ``source`` and the curve.
    """
    topo = topology or load_topology()
    wanted = {c.name for c in topo.curves}
    found: dict[str, np.ndarray] = {}
    for c in curves:
        if c.name.endswith(RIGHT_SUFFIX) and c.name[: -len(RIGHT_SUFFIX)] in wanted:
            continue
        if not c.name:
            raise TemplateError(f"{source}: holds a curve with no name (every curve must carry its topology name: "
                                f"on its part, its edge or its curve set)")
        if c.name not in wanted:
            raise TemplateError(f"{source}: unknown curve {c.name!r} (not in the wireframe topology)")
        if c.name in found:
            raise TemplateError(f"{source}: curve {c.name!r} appears twice")
        found[c.name] = _as_cubic_bezier(c, source)
    missing = [c.name for c in topo.curves if c.name not in found]
    if missing:
        raise TemplateError(f"{source}: curve {missing[0]!r} is missing"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    points = np.concatenate([found[c.name] for c in topo.curves])
    points = _orient_curves(points, topo, source)
    return Wireframe(name, points)


def _as_cubic_bezier(curve, path) -> np.ndarray:
    """(4, 3) poles of a curve that must be a non-rational cubic Bezier (one span, 4 poles)."""
    poles = np.asarray(curve.poles, float)
    if not np.isfinite(poles).all():
        raise TemplateError(f"{path}: curve {curve.name!r} has a pole that is not a number")
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


def _orient_curves(points: np.ndarray, topo: Topology, path) -> np.ndarray:
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


def _left_name(curve: str, topo: Topology) -> tuple[str, bool]:
    """(left-half curve name, whether ``curve`` named its right twin)."""
    names = {c.name for c in topo.curves}
    if curve in names:
        return curve, False
    if curve.endswith(RIGHT_SUFFIX) and curve[: -len(RIGHT_SUFFIX)] in names:
        return curve[: -len(RIGHT_SUFFIX)], True
    raise TemplateError(f"unknown curve {curve!r} (not in the wireframe topology)")


def _left_junction(junction: str, topo: Topology) -> tuple[str, bool]:
    if junction in topo.junctions:
        return junction, False
    if junction.endswith(RIGHT_SUFFIX) and junction[: -len(RIGHT_SUFFIX)] in topo.junctions:
        return junction[: -len(RIGHT_SUFFIX)], True
    raise TemplateError(f"unknown junction {junction!r} (not in the wireframe topology)")


def _on_symmetry_plane(cp: np.ndarray, topo: Topology) -> np.ndarray:
    """Control points with x = 0 at every symmetry-plane junction and along the curves lying in
    the plane (both ends on it), so the mirror half meets this one."""
    cp = cp.copy()
    for junction in topo.symmetry_junctions:
        cp[topo.junction_groups()[junction], 0] = 0.0
    for c in topo.curves:
        if c.start in topo.symmetry_junctions and c.end in topo.symmetry_junctions:
            cp[POINTS_PER_CURVE * c.index:POINTS_PER_CURVE * (c.index + 1), 0] = 0.0
    return cp


# ---- wireframe JSON: the plain-data twin of the wireframe STEP file (the FreeCAD workbench's
# way in and out of carbody, and any script's)

#: The ``format`` field of a wireframe JSON file.
JSON_FORMAT = "carbody-wireframe"


def wireframe_json(wireframe: Wireframe, both_halves: bool = False) -> dict:
    """The wireframe as JSON-ready data: ``{"format", "name", "units": "mm", "curves": [{"name",
    "start", "end", "poles": 4 x [x, y, z]}]}``, curves in the topology's order (with
    ``both_halves`` the mirror half follows, its junctions named ``*_right`` off the symmetry
    plane)."""
    topo = load_topology()
    ends = {c.name: (c.start, c.end) for c in topo.curves}

    def twin(junction: str) -> str:
        return junction if junction in topo.symmetry_junctions else junction + RIGHT_SUFFIX

    curves = []
    for name, poles in wireframe.named_curves(both_halves):
        right = name not in ends
        start, end = ends[name[: -len(RIGHT_SUFFIX)] if right else name]
        if right:
            start, end = twin(start), twin(end)
        curves.append({"name": name, "start": start, "end": end, "poles": np.asarray(poles, float).tolist()})
    return {"format": JSON_FORMAT, "name": wireframe.name, "units": "mm", "curves": curves}


def write_wireframe_json(path: str | Path, wireframe: Wireframe, both_halves: bool = False) -> Path:
    """Write :func:`wireframe_json` to ``path`` (atomically)."""
    import json

    from carbody.occ.step_curves import atomic_write

    text = json.dumps(wireframe_json(wireframe, both_halves), indent=1)
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def _read_json_curves(path: Path):
    import json

    from carbody.occ.step_curves import NamedCurve

    if not path.is_file():
        raise TemplateError(f"{path}: no such file")
    try:
        data = json.loads(path.read_text())
        if data.get("format") != JSON_FORMAT:
            raise ValueError(f"its format is {data.get('format')!r}, not {JSON_FORMAT!r}")
        scale = {"mm": 1.0, "m": 1000.0, "cm": 10.0, "in": 25.4}[data.get("units", "mm")]
        curves = []
        for c in data["curves"]:
            poles = np.asarray(c["poles"], float) * scale
            if poles.ndim != 2 or poles.shape[1] != 3:
                raise ValueError(f"curve {c.get('name')!r} has poles of shape {poles.shape}")
            curves.append(NamedCurve(str(c.get("name", "")), poles, len(poles) - 1, 1, False))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise TemplateError(f"{path}: not a carbody wireframe JSON file ({exc})") from None
    return str(data.get("name", "")), curves


# ---- wireframes from CadQuery and build123d objects


def as_wireframe(obj, name: str | None = None) -> Wireframe:
    """A :class:`Wireframe` from what a script has in hand.

    Args:
        obj: a :class:`Wireframe`; a wireframe file (STEP or JSON path); a build123d shape whose
            edges (or children) carry the curve names as ``label`` (a ``Compound`` of labelled
            edges, as ``carbody.reconstruct(...).wireframe_build123d()`` gives); a CadQuery
            ``Assembly`` with one named child per curve (CadQuery shapes carry no names of
            their own); or a dict {curve name: (4, 3) poles or an edge}. Right-half curves are
            ignored; the left half is the model.
        name: the car (default: the object's label / name).
    Raises:
        TemplateError: an unnamed, unknown, missing or non-cubic curve, or curves that do not
            meet at their junctions.
    """
    if isinstance(obj, Wireframe):
        return obj
    if isinstance(obj, (str, Path)):
        return read_wireframe(obj)
    from carbody.occ.step_curves import NamedCurve, edge_curve

    module = type(obj).__module__.split(".")[0]
    if isinstance(obj, dict):
        curves = [NamedCurve(k, np.asarray(v, float), len(v) - 1) if not hasattr(v, "wrapped") and
                  not _is_occ_edge(v) else edge_curve(_occ(v), k) for k, v in obj.items()]
        return wireframe_from_curves(curves, name or "car", "the curves given")
    if module == "build123d":
        curves = [edge_curve(e, label) for label, e in _build123d_edges(obj)]
        return wireframe_from_curves(curves, name or getattr(obj, "label", "") or "car", "the build123d shape")
    if module == "cadquery":
        import cadquery as cq

        if not isinstance(obj, cq.Assembly):
            raise TemplateError("a CadQuery shape carries no curve names: put one edge per curve in a "
                                "cq.Assembly, each child named after its curve")
        curves = [edge_curve(e, label) for label, e in _cadquery_edges(obj)]
        return wireframe_from_curves(curves, name or obj.name or "car", "the CadQuery assembly")
    raise TemplateError(f"cannot read a wireframe from a {type(obj).__name__}")


def _is_occ_edge(v) -> bool:
    return type(v).__name__ == "TopoDS_Edge"


def _occ(v):
    return getattr(v, "wrapped", v)


def _build123d_edges(shape, label: str = "") -> list[tuple[str, object]]:
    """(label, TopoDS_Edge) of every edge of a build123d shape, named by the nearest label."""
    from carbody.occ.shapes import sub_shapes

    own = getattr(shape, "label", "") or label
    children = list(getattr(shape, "children", ()) or ())
    if children:
        return [pair for child in children for pair in _build123d_edges(child, own)]
    edges = sub_shapes(shape.wrapped, "edge")
    if len(edges) == 1:
        return [(own, edges[0])]
    # a shape of several edges: each edge's own label, if the script gave one
    return [(getattr(e, "label", "") or "", e.wrapped) for e in shape.edges()]


def _cadquery_edges(assy) -> list[tuple[str, object]]:
    """(child name, located TopoDS_Edge) of every single-edge child of a CadQuery assembly."""
    from carbody.occ.shapes import sub_shapes

    out = []

    def walk(node, loc):
        here = loc * node.loc if loc is not None else node.loc
        if node.obj is not None:
            shapes = node.obj.vals() if hasattr(node.obj, "vals") else [node.obj]
            for shape in shapes:
                moved = shape.moved(here) if hasattr(shape, "moved") else shape
                edges = sub_shapes(moved.wrapped, "edge")
                out.extend((node.name if len(edges) == 1 else "", e) for e in edges)
        for child in node.children:
            walk(child, here)

    walk(assy, None)
    return out
