"""OCCT shapes of carbody objects, and their CadQuery / build123d views.

Users never need OCCT handles: :func:`as_cadquery` and :func:`as_build123d` wrap any shape the
pipeline makes as the shape class of those libraries (they share one OCP build).
"""
from __future__ import annotations

import numpy as np


def sub_shapes(shape, kind: str) -> list:
    """The sub-shapes of one kind ("face", "edge", "wire", "shell"), downcast, in explorer order."""
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    enum, cast = {"face": (TopAbs_FACE, TopoDS.Face_s), "edge": (TopAbs_EDGE, TopoDS.Edge_s),
                  "wire": (TopAbs_WIRE, TopoDS.Wire_s), "shell": (TopAbs_SHELL, TopoDS.Shell_s)}[kind]
    out, explorer = [], TopExp_Explorer(shape, enum)
    while explorer.More():
        out.append(cast(explorer.Current()))
        explorer.Next()
    return out


def curves_compound(curves: list[tuple[str, np.ndarray]]):
    """A TopoDS_Compound of Bezier edges, one per (name, (n, 3) poles mm)."""
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    from carbody.occ.step_curves import bezier_edge

    builder = BRep_Builder()
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    for _, poles in curves:
        builder.Add(compound, bezier_edge(np.asarray(poles, float)))
    return compound


def as_cadquery(shape):
    """A ``cadquery.Shape`` (Compound, Shell, ...) wrapping a TopoDS shape."""
    import cadquery as cq

    return cq.Shape.cast(shape)


def as_build123d(shape):
    """A ``build123d`` shape (Compound, Shell, ...) wrapping a TopoDS shape."""
    import build123d as bd

    return bd.Shape.cast(shape)


def thicken(shape, thickness_mm: float):
    """A solid skin: ``shape`` (a shell, or a cadquery/build123d one) offset by ``thickness_mm``.

    Uses OCCT's simple thick-solid offset, which works on open shells of Bezier faces where the
    general offset algorithm (build123d's ``thicken``) fails. Negative thickness goes inwards.

    Returns:
        a shape of the same kind as given: TopoDS_Solid, ``cadquery.Solid`` or ``build123d.Solid``.
    """
    from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeThickSolid

    from carbody.errors import CarbodyError

    wrapped = getattr(shape, "wrapped", shape)
    maker = BRepOffsetAPI_MakeThickSolid()
    maker.MakeThickSolidBySimple(wrapped, float(thickness_mm))
    maker.Build()
    if not maker.IsDone():
        raise CarbodyError(f"OCCT could not thicken the shape by {thickness_mm} mm")
    solid = maker.Shape()
    module = type(shape).__module__.split(".")[0]
    if module == "cadquery":
        return as_cadquery(solid)
    if module == "build123d":
        return as_build123d(solid)
    return solid
