"""The car as parametric FreeCAD objects: editable curves and a body recomputed from them.

* ``CarbodyCurve`` (Part::FeaturePython), one per wireframe curve of both halves: its shape is
  the cubic Bezier through its ``Poles`` (mm, editable in the property view). Moving a pole
  keeps the car whole: the mirror twin follows (x negated), every curve ending at a moved end
  pole's junction follows with its own end (on both halves), and points on the symmetry plane
  stay at x = 0 (a centre curve's poles all, a curve's end on a centre junction).
* ``CarBody`` (Part::FeaturePython): the sewn Bezier shell of both halves, recomputed from the
  curves it links (``Curves``) by ``carbody surface`` (a separate process: FreeCAD has its own
  OCCT). Each face's region and colour are kept (``FaceRegions``, ``FaceColours``; the GUI
  paints them); a region that folds after an edit is one line in the report view and in
  ``Folds`` / ``Status``; a wireframe carbody cannot surface is one line and the object is
  marked in error, the last body kept.
* ``CarRegion`` (Part::FeaturePython), one per region: the body's faces of that region, in its
  colour, recomputed with the body.

Everything here runs headless (``freecadcmd``); the view providers are added only with the GUI.
"""
import json
import os
import tempfile

import FreeCAD
import Part

from carbody_wb import core

RIGHT = "_right"


class _Syncing:
    """Set while one edit is carried to the other curves, so their own changes do not recurse."""

    active = False


def _vectors(points):
    return [FreeCAD.Vector(*map(float, p)) for p in points]


def _restoring(obj):
    return "Restore" in getattr(obj, "State", ())


class CarbodyCurve:
    """Proxy of one wireframe curve (see module docstring)."""

    def __init__(self, obj, entry, on_plane):
        obj.Proxy = self
        obj.addProperty("App::PropertyVectorList", "Poles", "carbody", "the curve's four Bezier poles (mm): move them")
        for name, doc in (("CurveName", "the curve's name in carbody's topology"),
                          ("StartJunction", "the junction its first pole lies on"),
                          ("EndJunction", "the junction its last pole lies on"),
                          ("Side", "left, right (the mirror twin) or centre (on the symmetry plane)")):
            obj.addProperty("App::PropertyString", name, "carbody", doc)
            obj.setEditorMode(name, 1)  # read-only
        obj.addProperty("App::PropertyBool", "StartOnPlane", "carbody", "its first pole stays at x = 0")
        obj.addProperty("App::PropertyBool", "EndOnPlane", "carbody", "its last pole stays at x = 0")
        for name in ("StartOnPlane", "EndOnPlane"):
            obj.setEditorMode(name, 1)
        obj.setEditorMode("Placement", 2)  # the poles say where the curve is
        name = entry["name"]
        obj.CurveName, obj.StartJunction, obj.EndJunction = name, entry["start"], entry["end"]
        obj.StartOnPlane, obj.EndOnPlane = entry["start"] in on_plane, entry["end"] in on_plane
        obj.Side = "right" if name.endswith(RIGHT) else "centre" if obj.StartOnPlane and obj.EndOnPlane else "left"
        obj.Label = name
        _Syncing.active = True
        try:
            obj.Poles = _vectors(entry["poles"])
        finally:
            _Syncing.active = False

    def execute(self, obj):
        curve = Part.BezierCurve()
        curve.setPoles(list(obj.Poles))
        obj.Shape = curve.toShape()

    def onChanged(self, obj, prop):
        if prop == "Poles" and not _Syncing.active and not _restoring(obj) and hasattr(obj, "EndOnPlane"):
            _Syncing.active = True
            try:
                carry_edit(obj)
            finally:
                _Syncing.active = False

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    dumps, loads = __getstate__, __setstate__


def _curves_beside(obj):
    """{curve name: object} of the curves in the same wireframe group as ``obj``."""
    groups = [o for o in obj.InList if o.isDerivedFrom("App::DocumentObjectGroup")]
    members = groups[0].Group if groups else obj.Document.Objects
    return {o.CurveName: o for o in members if hasattr(o, "CurveName")}


def _twin_name(name):
    return name[: -len(RIGHT)] if name.endswith(RIGHT) else name + RIGHT


def carry_edit(obj):
    """Carry an edit of ``obj``'s poles to the rest of the car: symmetry plane, mirror twin,
    and every curve end on the junctions of ``obj`` and its twin."""
    poles = [FreeCAD.Vector(p) for p in obj.Poles]
    if len(poles) != 4:
        return
    if obj.Side == "centre":
        poles = [FreeCAD.Vector(0, p.y, p.z) for p in poles]
    if obj.StartOnPlane:
        poles[0].x = 0.0
    if obj.EndOnPlane:
        poles[-1].x = 0.0
    _set_poles(obj, poles)
    curves = _curves_beside(obj)
    touched = [obj]
    twin = curves.get(_twin_name(obj.CurveName))
    if twin is not None and obj.Side != "centre":
        _set_poles(twin, [FreeCAD.Vector(-p.x, p.y, p.z) for p in poles])
        touched.append(twin)
    for curve in touched:
        ends = {curve.StartJunction: curve.Poles[0], curve.EndJunction: curve.Poles[-1]}
        for other in curves.values():
            if other in touched:
                continue
            new = [FreeCAD.Vector(p) for p in other.Poles]
            if other.StartJunction in ends:
                new[0] = FreeCAD.Vector(ends[other.StartJunction])
            if other.EndJunction in ends:
                new[-1] = FreeCAD.Vector(ends[other.EndJunction])
            _set_poles(other, new)


def _set_poles(obj, poles):
    if any((a - b).Length > 1e-12 for a, b in zip(obj.Poles, poles)):
        obj.Poles = poles


def move_junction(where, junction, delta, handles=True):
    """Move one junction by ``delta`` (x, y, z mm), as a node of a Bezier path moves: every
    curve's end pole on it and, with ``handles``, the pole next to it (so the curves leave the
    junction in the directions they did), on both halves; the symmetry plane is kept.

    Args:
        where: a car's wireframe group, or a document (every car in it).

    Returns:
        the curve objects edited.
    """
    delta = FreeCAD.Vector(*delta)
    curves = [o for o in (where.Group if hasattr(where, "Group") else where.Objects) if hasattr(o, "CurveName")]
    if any((o.StartJunction == junction and o.StartOnPlane) or (o.EndJunction == junction and o.EndOnPlane)
           for o in curves):
        delta.x = 0.0  # a junction on the symmetry plane moves in it
    mirrored = FreeCAD.Vector(-delta.x, delta.y, delta.z)
    twin = junction[: -len(RIGHT)] if junction.endswith(RIGHT) else junction + RIGHT
    edited = []
    _Syncing.active = True
    try:
        for obj in curves:
            poles = [FreeCAD.Vector(p) for p in obj.Poles]
            for name, d in ((junction, delta), (twin, mirrored)):
                for end, ends in ((obj.StartJunction, (0, 1)), (obj.EndJunction, (3, 2))):
                    if end == name:
                        for k in ends[: 2 if handles else 1]:
                            poles[k] = poles[k] + d
            if any((a - b).Length > 0 for a, b in zip(poles, obj.Poles)):
                obj.Poles = poles
                edited.append(obj)
    finally:
        _Syncing.active = False
    if not edited:
        raise core.CarbodyWorkbenchError(f"no curve ends on junction {junction!r}")
    for obj in edited:  # the curves on the symmetry plane stay in it
        if obj.Side != "centre":
            continue
        _Syncing.active = True
        try:
            carry_edit(obj)
        finally:
            _Syncing.active = False
    return edited


class CarBody:
    """Proxy of the sewn body (see module docstring)."""

    def __init__(self, obj, curves, car_name):
        obj.Proxy = self
        obj.addProperty("App::PropertyLinkList", "Curves", "carbody", "the wireframe curves the body is made from")
        obj.addProperty("App::PropertyString", "CarName", "carbody", "the car")
        obj.addProperty("App::PropertyStringList", "FaceRegions", "carbody", "the region of each face")
        obj.addProperty("App::PropertyColorList", "FaceColours", "carbody", "the colour of each face (its region's)")
        obj.addProperty("App::PropertyStringList", "Folds", "carbody", "regions that fold, one line each")
        obj.addProperty("App::PropertyString", "Status", "carbody", "the last recompute: valid, folds, or why not")
        for name in ("FaceRegions", "FaceColours", "Folds", "Status"):
            obj.setEditorMode(name, 1)
        obj.Curves, obj.CarName = curves, car_name

    def execute(self, obj):
        if getattr(self, "prebuilt", False):  # surfaced already (in the background): see add_car
            self.prebuilt = False
            return
        wire = body_wireframe_json(obj)
        with tempfile.TemporaryDirectory(prefix="carbody-fc-") as tmp:
            paths = {k: os.path.join(tmp, k) for k in ("wire.json", "body.step", "report.json")}
            with open(paths["wire.json"], "w") as f:
                json.dump(wire, f)
            try:
                core.run_carbody(core.surface_args(paths["wire.json"], paths["body.step"], paths["report.json"]))
            except core.CarbodyWorkbenchError as exc:
                line = str(exc).split(": error: ", 1)[-1]
                obj.Status = line
                FreeCAD.Console.PrintError(f"carbody: {obj.Label}: {line}\n")
                raise RuntimeError(line) from None
            shape, report = core.read_surfaced(paths["body.step"], paths["report.json"])
        apply_surfaced(obj, shape, report)

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    dumps, loads = __getstate__, __setstate__


def body_wireframe_json(obj):
    """The wireframe JSON data (left half) a CarBody is surfaced from: its curves' poles now."""
    return {"format": "carbody-wireframe", "name": obj.CarName, "units": "mm",
            "curves": [{"name": c.CurveName, "poles": [[p.x, p.y, p.z] for p in c.Poles]}
                       for c in obj.Curves if c.Side != "right"]}


def apply_surfaced(obj, shape, report):
    """Give a CarBody the shell ``carbody surface`` made (``shape``, read from its STEP file) and
    what its report says: each face's region and colour (matched by position), the folds."""
    faces = report["faces"]
    order = core.match_faces(shape.Faces, faces)
    obj.FaceRegions = [faces[k]["region"] for k in order]
    obj.FaceColours = [tuple(faces[k]["colour"]) for k in order]
    obj.Folds = report["folds"]
    shell = shape.Shells[0] if len(shape.Shells) == 1 else shape
    obj.Shape = shell
    if report["folds"]:
        obj.Status = report["folds"][0]
        for line in report["folds"]:
            FreeCAD.Console.PrintError(f"carbody: {line}\n")
    else:
        obj.Status = f"valid sewn shell, {len(shape.Faces)} faces" if shell.isValid() else "shell not valid"


class CarRegion:
    """Proxy of one region: the body's faces of that region."""

    def __init__(self, obj, body, region):
        obj.Proxy = self
        obj.addProperty("App::PropertyLink", "Body", "carbody", "the CarBody this region belongs to")
        obj.addProperty("App::PropertyString", "Region", "carbody", "the region's name")
        obj.addProperty("App::PropertyColor", "Colour", "carbody", "the region's colour")
        obj.setEditorMode("Region", 1)
        obj.Body, obj.Region, obj.Label = body, region, region

    def execute(self, obj):
        body = obj.Body
        picked = [f for f, r in zip(body.Shape.Faces, body.FaceRegions) if r == obj.Region]
        colours = [c for c, r in zip(body.FaceColours, body.FaceRegions) if r == obj.Region]
        if colours:
            obj.Colour = colours[0][:3]
        # the two mirror halves of a region need not touch: a compound holds them either way
        obj.Shape = Part.Compound(picked) if picked else Part.Shape()

    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    dumps, loads = __getstate__, __setstate__


if FreeCAD.GuiUp:
    class ViewProviderCarBody:
        """Paints every face in its region's colour."""

        def __init__(self, vobj):
            vobj.Proxy = self

        def attach(self, vobj):
            self.Object = vobj.Object

        def updateData(self, obj, prop):
            if prop in ("Shape", "FaceColours"):
                from PySide import QtCore

                # Part's own view provider resets the colours when the shape changes: paint after it
                QtCore.QTimer.singleShot(0, lambda: self.paint(obj))

        @staticmethod
        def paint(obj):
            if len(obj.FaceColours) == len(obj.Shape.Faces):
                obj.ViewObject.DiffuseColor = list(obj.FaceColours)

        def onChanged(self, vobj, prop):
            return

        def __getstate__(self):
            return None

        def __setstate__(self, state):
            return None

    class ViewProviderCarRegion(ViewProviderCarBody):
        @staticmethod
        def paint(obj):
            obj.ViewObject.ShapeColor = obj.Colour[:3]

        def updateData(self, obj, prop):
            if prop in ("Shape", "Colour"):
                from PySide import QtCore

                QtCore.QTimer.singleShot(0, lambda: self.paint(obj))


def add_car(doc, wire_json, surfaced=None):
    """Bring a wireframe (carbody's wireframe JSON data, both halves) into ``doc`` as parametric
    objects: a ``Wireframe`` group of CarbodyCurve objects, a ``Body`` group with the CarBody
    (labelled ``BodyShell``) and one CarRegion per region, and recompute.

    Args:
        surfaced: the body ``carbody surface`` already made of this wireframe, as
            :func:`carbody_wb.core.read_surfaced` gives it (shape, report): the Reconstruct
            command surfaces it in the background, so that the import does not wait for it.
            Without it the body's first recompute runs ``carbody surface`` (found as
            :func:`carbody_wb.core.carbody_command` says) and waits.
    Returns:
        (wireframe group, body group).
    """
    on_plane = ({c["start"] for c in wire_json["curves"] if c["name"].endswith(RIGHT)}
                | {c["end"] for c in wire_json["curves"] if c["name"].endswith(RIGHT)})
    on_plane = {j for j in on_plane if not j.endswith(RIGHT)}
    wire_group = doc.addObject("App::DocumentObjectGroup", "Wireframe")
    curves = []
    for entry in wire_json["curves"]:
        obj = doc.addObject("Part::FeaturePython", "Curve")
        CarbodyCurve(obj, entry, on_plane)
        if FreeCAD.GuiUp:
            obj.ViewObject.Proxy = 0
        wire_group.addObject(obj)
        curves.append(obj)
    body_group = doc.addObject("App::DocumentObjectGroup", "Body")
    body = doc.addObject("Part::FeaturePython", "CarBody")
    CarBody(body, curves, wire_json.get("name", "car"))
    body.Label = "BodyShell"
    if FreeCAD.GuiUp:
        ViewProviderCarBody(body.ViewObject)
    if surfaced is not None:  # (after the view provider: it paints the faces as they are set)
        apply_surfaced(body, *surfaced)
        body.Proxy.prebuilt = True
    body_group.addObject(body)
    doc.recompute()
    if body.Shape.isNull():
        raise core.CarbodyWorkbenchError(body.Status or "carbody could not surface the wireframe")
    for region in dict.fromkeys(body.FaceRegions):  # the topology's order, as the faces come
        obj = doc.addObject("Part::FeaturePython", "Region")
        CarRegion(obj, body, region)
        if FreeCAD.GuiUp:
            ViewProviderCarRegion(obj.ViewObject)
            obj.ViewObject.Visibility = False
        body_group.addObject(obj)
    doc.recompute()
    return wire_group, body_group
