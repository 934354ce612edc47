"""Checks of a sewn shell (OCCT): validity, free edges, tolerances, distance of points to faces."""
from __future__ import annotations

import numpy as np

from carbody.occ.shapes import sub_shapes


def free_edge_loops(shell) -> tuple[list, list]:
    """(closed wires, open wires) made of the shell's free edges (edges of one face only)."""
    from OCP.ShapeAnalysis import ShapeAnalysis_FreeBounds

    fb = ShapeAnalysis_FreeBounds(shell, False, False)
    return sub_shapes(fb.GetClosedWires(), "wire"), sub_shapes(fb.GetOpenWires(), "wire")


def edge_points(edge, n: int = 9) -> np.ndarray:
    """(n, 3) points along an edge (mm)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve

    c = BRepAdaptor_Curve(edge)
    t = np.linspace(c.FirstParameter(), c.LastParameter(), n)
    return np.array([[p.X(), p.Y(), p.Z()] for p in (c.Value(float(x)) for x in t)])


def max_tolerances(shape) -> dict[str, float]:
    """Largest tolerance of the shape's faces, edges and vertices (mm)."""
    from OCP.ShapeAnalysis import ShapeAnalysis_ShapeTolerance
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX

    st = ShapeAnalysis_ShapeTolerance()
    return {"face": st.Tolerance(shape, 1, TopAbs_FACE), "edge": st.Tolerance(shape, 1, TopAbs_EDGE),
            "vertex": st.Tolerance(shape, 1, TopAbs_VERTEX)}


def shell_checks(shell) -> dict:
    """The figures the tests assert: validity, face count, free-edge loops, tolerances.

    Returns:
        {valid, shape_type, faces, edges, free_edges, free_closed_loops, free_open_wires,
        free_length_mm, max_tolerance_mm}
    """
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.GProp import GProp_GProps
    from OCP.BRepGProp import BRepGProp
    n_faces = len(sub_shapes(shell, "face"))
    closed, open_ = free_edge_loops(shell)
    free_edges = [e for w in closed + open_ for e in sub_shapes(w, "edge")]
    length = 0.0
    for e in free_edges:
        props = GProp_GProps()
        BRepGProp.LinearProperties_s(e, props)
        length += props.Mass()
    tol = max_tolerances(shell)
    return {
        "valid": bool(BRepCheck_Analyzer(shell).IsValid()),
        "shape_type": shell.ShapeType().name,
        "faces": n_faces,
        "free_edges": len(free_edges),
        "free_closed_loops": len(closed),
        "free_open_wires": len(open_),
        "free_length_mm": length,
        "max_tolerance_mm": max(tol["edge"], tol["vertex"]),
    }


def invalid_faces(faces: list) -> list[int]:
    """Indices of the faces ``BRepCheck_Analyzer`` finds invalid on their own."""
    from OCP.BRepCheck import BRepCheck_Analyzer

    return [k for k, f in enumerate(faces) if not BRepCheck_Analyzer(f).IsValid()]


def points_to_faces_distance(faces: list, points: np.ndarray, margin: float = 1.0) -> np.ndarray:
    """Distance (mm) from each point (n, 3) to the nearest of ``faces`` (projection on the
    surfaces of the faces whose bounding box, grown by ``margin`` mm, holds the point)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRep import BRep_Tool
    from OCP.BRepBndLib import BRepBndLib
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt

    boxes, surfaces = [], []
    for f in faces:
        box = Bnd_Box()
        BRepBndLib.Add_s(f, box)
        boxes.append(box.Get())
        surfaces.append(BRep_Tool.Surface_s(f))
    boxes = np.array(boxes)
    out = np.full(len(points), np.inf)
    for k, p in enumerate(np.asarray(points, float)):
        hit = np.flatnonzero(np.all((p >= boxes[:, :3] - margin) & (p <= boxes[:, 3:] + margin), axis=1))
        for i in hit:
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), surfaces[i])
            if proj.NbPoints():
                out[k] = min(out[k], proj.LowerDistance())
    return out
