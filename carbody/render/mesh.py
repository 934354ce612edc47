"""OCCT shapes -> triangle meshes, one per face, each keeping its region name.

The faces are meshed together (one ``BRepMesh_IncrementalMesh`` over a compound) so edges shared
by two faces get the same nodes and the rendered surface has no cracks.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from carbody.errors import RenderError

#: Regions rendered as glass; every other face is paint.
GLASS_REGIONS = ("windshield", "rear_window", "side_window")

#: Linear deflection of the tessellation as a fraction of the shape's bounding-box diagonal.
DEFLECTION_REL = 1e-3

#: Angular deflection of the tessellation, radians. On a car's panels the linear deflection
#: governs; the angle only refines tight folds, so a crumpled body (a fit far outside the
#: library) would otherwise mesh into a few hundred thousand triangles.
ANGULAR_DEFLECTION = 0.5


@dataclass
class FaceMesh:
    """A triangulated face.

    Attributes:
        name: region name (``""`` when the input carried none).
        vertices: (n, 3) float, model units (mm for bodies).
        triangles: (m, 3) int, counter-clockwise seen from the face's outer side.
    """

    name: str
    vertices: np.ndarray
    triangles: np.ndarray


def is_glass(name: str) -> bool:
    """True when a face named ``name`` (e.g. ``"side_window"``, ``"windshield_right_2"``) is glass."""
    return any(name == g or name.startswith(g + "_") or name.startswith(g + ".") for g in GLASS_REGIONS)


def named_faces(shape_or_faces: Any) -> list[tuple[str, Any]]:
    """[(name, TopoDS_Face)] of any input the renderer accepts.

    Accepted: a ``TopoDS_Shape``; a cadquery/build123d object (``.wrapped``) or a Workplane
    (``.vals()``); an object with ``.faces`` = [(name, face)] such as
    :class:`carbody.surface.Body` (its ``.shape`` is used when it has more faces, e.g. the
    mirrored half, with names carried over where the face is the same); or an iterable of
    shapes or (name, shape) pairs.
    """
    from OCP.TopoDS import TopoDS_Shape

    from carbody.occ.shapes import sub_shapes

    def faces_of(shape) -> list:
        return sub_shapes(shape, "face")

    def as_shape(obj):
        if isinstance(obj, TopoDS_Shape):
            return obj
        if hasattr(obj, "wrapped") and isinstance(obj.wrapped, TopoDS_Shape):
            return obj.wrapped
        if hasattr(obj, "vals") and callable(obj.vals):
            return [as_shape(v) for v in obj.vals()]
        raise RenderError(f"cannot render a {type(obj).__name__} (need an OCCT shape or faces)")

    x = shape_or_faces
    if isinstance(x, TopoDS_Shape) or hasattr(x, "wrapped"):
        return [("", f) for f in faces_of(as_shape(x))]
    if hasattr(x, "faces") and isinstance(getattr(x, "faces"), (list, tuple)):
        named = [(str(n), f) for n, f in x.faces]
        whole = getattr(x, "shape", None)
        if whole is not None:
            all_faces = faces_of(as_shape(whole))
            if len(all_faces) > len(named):
                return _name_by_geometry(all_faces, named)
        return [(n, g) for n, f in named for g in faces_of(as_shape(f))]
    if hasattr(x, "vals") and callable(x.vals):
        return [("", f) for s in as_shape(x) for f in faces_of(s)]
    if isinstance(x, Iterable) and not isinstance(x, (str, bytes)):
        out = []
        for item in x:
            if isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str):
                out += [(item[0], f) for f in faces_of(as_shape(item[1]))]
            else:
                shp = as_shape(item)
                for s in (shp if isinstance(shp, list) else [shp]):
                    out += [("", f) for f in faces_of(s)]
        return out
    raise RenderError(f"cannot render a {type(x).__name__} (need an OCCT shape or faces)")


def _name_by_geometry(all_faces: list, named: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """Names for every face of a whole shape from a list of named faces that may cover only one
    half: a face is named after the named face whose centre matches its own or its mirror's."""
    def centre(face) -> np.ndarray:
        from OCP.Bnd import Bnd_Box
        from OCP.BRepBndLib import BRepBndLib

        box = Bnd_Box()
        BRepBndLib.Add_s(face, box)
        x0, y0, z0, x1, y1, z1 = box.Get()
        return np.array([x0 + x1, y0 + y1, z0 + z1]) / 2

    ref = np.array([centre(f) for _, f in named]) if named else np.zeros((0, 3))
    names = [n for n, _ in named]
    out = []
    for f in all_faces:
        c = centre(f)
        name = ""
        if len(ref):
            dist = np.minimum(np.linalg.norm(ref - c, axis=1),
                              np.linalg.norm(ref - c * [-1.0, 1.0, 1.0], axis=1))
            name = names[int(np.argmin(dist))]
        out.append((name, f))
    return out


def tessellate(shape_or_faces: Any, deflection: float | None = None) -> list[FaceMesh]:
    """Triangulate every face; see :func:`named_faces` for the inputs accepted.

    Args:
        deflection: linear deflection in model units; default ``DEFLECTION_REL`` × diagonal.

    Returns:
        One :class:`FaceMesh` per face that meshes (degenerate faces are skipped).

    Raises:
        RenderError: no faces, or no face could be meshed.
    """
    from OCP.Bnd import Bnd_Box
    from OCP.BRep import BRep_Builder, BRep_Tool
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_REVERSED
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS_Compound

    faces = named_faces(shape_or_faces)
    if not faces:
        raise RenderError("nothing to render: the shape has no faces")
    compound = TopoDS_Compound()
    builder = BRep_Builder()
    builder.MakeCompound(compound)
    for _, f in faces:
        builder.Add(compound, f)
    if deflection is None:
        box = Bnd_Box()
        BRepBndLib.Add_s(compound, box)
        x0, y0, z0, x1, y1, z1 = box.Get()
        deflection = DEFLECTION_REL * float(np.linalg.norm([x1 - x0, y1 - y0, z1 - z0]) or 1.0)
    BRepMesh_IncrementalMesh(compound, float(deflection), False, ANGULAR_DEFLECTION, False)

    meshes = []
    for name, face in faces:
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0:
            continue
        trsf = loc.Transformation()
        identity = loc.IsIdentity()
        verts = np.empty((tri.NbNodes(), 3))
        for i in range(tri.NbNodes()):
            p = tri.Node(i + 1)
            if not identity:
                p = p.Transformed(trsf)
            verts[i] = (p.X(), p.Y(), p.Z())
        tris = np.array([tri.Triangle(i + 1).Get() for i in range(tri.NbTriangles())], dtype=np.int64) - 1
        if face.Orientation() == TopAbs_REVERSED:
            tris = tris[:, ::-1]
        meshes.append(FaceMesh(name, verts, tris))
    if not meshes:
        raise RenderError("nothing to render: no face of the shape could be meshed")
    return meshes


def mirrored(meshes: list[FaceMesh]) -> list[FaceMesh]:
    """The meshes reflected in the symmetry plane x = 0 (winding flipped so normals stay outward)."""
    return [FaceMesh(m.name, m.vertices * [-1.0, 1.0, 1.0], m.triangles[:, ::-1].copy()) for m in meshes]
