"""Surfaces (paper IV–V): 13 regions -> skeletons -> control nets -> Bezier faces -> one shell.

Public API::

    from carbody.surface import build_body, Body
    body = build_body(wireframe)   # body.shape (TopoDS_Shell), body.faces, body.report
    body = surface_wireframe(edited)   # the same, from a Wireframe or a CadQuery/build123d
                                       # object, refusing a body that folds (FoldError)

Stages, one module each: :mod:`~carbody.surface.regions` (boundary loops, projection,
samples), :mod:`~carbody.surface.skeleton` (optimal pairs, Algorithm 1),
:mod:`~carbody.surface.control_net` (control curves, DTW, quad nets),
:mod:`~carbody.surface.arc_layout` (the ribs of a region whose projected outline folds, from its
boundary curves alone), :mod:`~carbody.surface.quality` (G0/G1/Jacobian), :mod:`~carbody.surface.folds` (regions that
turn back over themselves),
:mod:`~carbody.surface.body` (the pipeline). :mod:`~carbody.surface.stress` makes hard
wireframes to test it on.
OCCT lives in :mod:`carbody.occ` (faces, sewing, checks, step_body).
"""
from carbody.surface.body import Body, build_body, region_patches, skeletons, surface_wireframe

__all__ = ["Body", "build_body", "region_patches", "skeletons", "surface_wireframe"]
