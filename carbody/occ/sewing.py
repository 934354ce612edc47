"""Sewing faces into one shell (OCCT ``BRepBuilderAPI_Sewing``)."""
from __future__ import annotations

from carbody.tolerances import SEW_TOL_MM


def sew_faces(faces: list, tolerance: float = SEW_TOL_MM):
    """Sew faces into one shell.

    Args:
        faces: TopoDS_Face list (edges of neighbours meet exactly; see :mod:`carbody.occ.faces`).
        tolerance: sewing tolerance, mm.
    Returns:
        (TopoDS_Shell, sewn faces in input order).
    Raises:
        SurfaceError: sewing did not give exactly one shell.
    """
    from carbody.errors import SurfaceError
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.TopoDS import TopoDS

    from carbody.occ.shapes import sub_shapes

    sewing = BRepBuilderAPI_Sewing(tolerance, True, True, False, False)  # no cutting: edges match
    for f in faces:
        sewing.Add(f)
    sewing.Perform()
    result = sewing.SewedShape()
    shells = sub_shapes(result, "shell")
    if len(shells) != 1:
        raise SurfaceError(f"sewing the faces gave {len(shells)} shells, not one")
    sewn = [TopoDS.Face_s(sewing.Modified(f)) if sewing.IsModified(f) else f for f in faces]
    return shells[0], sewn
