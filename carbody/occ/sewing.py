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
        AssertionError: sewing did not give exactly one shell (a construction bug).
    """
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    sewing = BRepBuilderAPI_Sewing(tolerance, True, True, False, False)  # no cutting: edges match
    for f in faces:
        sewing.Add(f)
    sewing.Perform()
    result = sewing.SewedShape()
    shells = []
    ex = TopExp_Explorer(result, TopAbs_SHELL)
    while ex.More():
        shells.append(TopoDS.Shell_s(ex.Current()))
        ex.Next()
    if len(shells) != 1:
        raise AssertionError(f"sewing gave {len(shells)} shells, not one")
    sewn = [TopoDS.Face_s(sewing.Modified(f)) if sewing.IsModified(f) else f for f in faces]
    return shells[0], sewn
