"""Bicubic Bezier faces with exact boundary edges (OCCT boundary).

A face is a ``Geom_BezierSurface`` on its whole [0, 1]² domain. Its boundary wire runs
v = 0 (u 0 -> 1), u = 1 (v 0 -> 1), v = 1 (u 1 -> 0), u = 0 (v 1 -> 0); each side may be split
into several edges (where a neighbouring face has a corner on the same wireframe curve). Every
edge's 3D curve is the exact cubic sub-arc of the side's iso-curve (de Casteljau, in numpy) and
its pcurve the matching straight segment in (u, v), parametrised alike, so the edge is
same-parameter by construction and neighbours' edges coincide.
"""
from __future__ import annotations

import numpy as np

from carbody.surface.regions import split_bezier

#: Tolerance given to faces, edges and vertices (mm): the construction is exact.
BUILD_TOL_MM = 1e-7

_SIDE_ORDER = ("v0", "u1", "v1", "u0")


def _side_poles(net: np.ndarray, side: str) -> np.ndarray:
    """(4, 3) poles of a side's iso-curve, in increasing side parameter."""
    return {"v0": net[:, 0], "v1": net[:, 3], "u0": net[0, :], "u1": net[3, :]}[side]


def _side_uv(side: str, p: float) -> tuple[float, float]:
    return {"v0": (p, 0.0), "v1": (p, 1.0), "u0": (0.0, p), "u1": (1.0, p)}[side]


def boundary_pieces(net: np.ndarray, splits: dict[str, np.ndarray]):
    """The face's boundary edges in wire order: [(poles (4, 3), uv start, uv end)].

    Args:
        net: (4, 4, 3) float, mm, poles [u, v].
        splits: side -> sorted split parameters in [0, 1], ends included.
    """
    out = []
    for side in _SIDE_ORDER:
        p = np.asarray(splits.get(side, (0.0, 1.0)), float)
        poles = _side_poles(net, side)
        pieces = list(zip(p[:-1], p[1:]))
        backwards = side in ("v1", "u0")
        if backwards:
            pieces = pieces[::-1]
        for a, b in pieces:
            sub = split_bezier(poles, a, b)
            if backwards:
                out.append((sub[::-1], _side_uv(side, b), _side_uv(side, a)))
            else:
                out.append((sub, _side_uv(side, a), _side_uv(side, b)))
    return out


def bezier_face(net: np.ndarray, splits: dict[str, np.ndarray] | None = None):
    """A TopoDS_Face on the bicubic Bezier surface of ``net`` with exact, split boundary edges.

    Args:
        net: (4, 4, 3) float, mm; ``net[i, j]`` is the pole at (u_i, v_j).
        splits: optional side -> split parameters (see :func:`boundary_pieces`).
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.Geom import Geom_BezierCurve, Geom_BezierSurface
    from OCP.Geom2d import Geom2d_BezierCurve
    from OCP.gp import gp_Pnt, gp_Pnt2d
    from OCP.TColgp import TColgp_Array1OfPnt, TColgp_Array1OfPnt2d, TColgp_Array2OfPnt
    from OCP.TopoDS import TopoDS_Face, TopoDS_Wire

    net = np.asarray(net, float)
    rows = net.tolist()
    arr = TColgp_Array2OfPnt(1, 4, 1, 4)
    for i in range(4):
        for j in range(4):
            arr.SetValue(i + 1, j + 1, gp_Pnt(*rows[i][j]))
    surface = Geom_BezierSurface(arr)
    builder = BRep_Builder()
    face = TopoDS_Face()
    builder.MakeFace(face, surface, BUILD_TOL_MM)
    wire = TopoDS_Wire()
    builder.MakeWire(wire)

    pieces = boundary_pieces(net, splits or {})
    vertices = [BRepBuilderAPI_MakeVertex(gp_Pnt(*poles[0].tolist())).Vertex() for poles, _, _ in pieces]
    for k, (poles, uv0, uv1) in enumerate(pieces):
        cp = TColgp_Array1OfPnt(1, 4)
        for i, pole in enumerate(poles.tolist()):
            cp.SetValue(i + 1, gp_Pnt(*pole))
        uv = TColgp_Array1OfPnt2d(1, 2)
        uv.SetValue(1, gp_Pnt2d(*uv0))
        uv.SetValue(2, gp_Pnt2d(*uv1))
        # the vertices are the sub-arc's end poles (its neighbours' to rounding): parameters 0 and 1,
        # what BRepLib_MakeEdge's projection finds for a vertex within tolerance of an end, told
        edge = BRepBuilderAPI_MakeEdge(Geom_BezierCurve(cp), vertices[k], vertices[(k + 1) % len(pieces)],
                                       0.0, 1.0).Edge()
        builder.UpdateEdge(edge, Geom2d_BezierCurve(uv), face, BUILD_TOL_MM)
        builder.Add(wire, edge)
    wire.Closed(True)
    builder.Add(face, wire)
    return face
