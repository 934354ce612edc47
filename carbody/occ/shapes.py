"""OCCT shapes of carbody objects, and their CadQuery / build123d views.

Users never need OCCT handles: :func:`as_cadquery` and :func:`as_build123d` wrap any shape the
pipeline makes as the shape class of those libraries (they share one OCP build).
"""
from __future__ import annotations

import numpy as np


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
