"""carbody inside FreeCAD, without the GUI: run the ``carbody`` command, bring its STEP results in.

FreeCAD has its own OCCT build, so carbody runs as a separate process, found as
:func:`carbody_command` says. A reconstruction comes in as parametric objects
(:mod:`carbody_wb.model`: curves with editable poles, a body recomputed from them); plain STEP
files as named Part objects (:func:`import_step_parts`), their curve and region names from
``carbody parts FILE --json``, matched to the shapes FreeCAD reads by position, so the import
does not depend on the order a STEP reader lists things in.
"""
import json
import math
import os
import shlex
import shutil
import subprocess

import FreeCAD
import Part

PARAM_PATH = "User parameter:BaseApp/Preferences/Mod/carbody"


class CarbodyWorkbenchError(Exception):
    """A one-line reason the workbench could not do what was asked."""


#: The workbench's own folder, symlinks resolved (a link in FreeCAD's Mod/ to a checkout).
WORKBENCH_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))


def carbody_command():
    """The carbody command as an argument list, the first of: ``$CARBODY_COMMAND``; the
    preference (Preferences > carbody, ``CarbodyCommand``; the **carbody command…** button);
    the ``carbody`` of a virtual environment (``.venv`` or ``venv``) in the checkout the
    workbench was linked or copied from (:func:`venv_carbody`); ``carbody`` on ``PATH``."""
    text = os.environ.get("CARBODY_COMMAND") or FreeCAD.ParamGet(PARAM_PATH).GetString("CarbodyCommand", "")
    if text.strip():
        return shlex.split(text)
    found = venv_carbody() or shutil.which("carbody")
    return [found or "carbody"]


def venv_carbody(start=None):
    """The ``carbody`` program of a virtual environment beside the workbench: ``.venv/bin`` or
    ``venv/bin`` (``Scripts`` on Windows) in its folder or any folder above it; None if none."""
    here = os.path.realpath(start or WORKBENCH_DIR)
    while True:
        for venv in (".venv", "venv"):
            for exe in (os.path.join(venv, "bin", "carbody"), os.path.join(venv, "Scripts", "carbody.exe")):
                path = os.path.join(here, exe)
                if os.path.isfile(path) and os.access(path, os.X_OK):
                    return path
        parent = os.path.dirname(here)
        if parent == here:
            return None
        here = parent


def set_carbody_command(text):
    FreeCAD.ParamGet(PARAM_PATH).SetString("CarbodyCommand", text)


def resolve_command(command=None):
    """The carbody command with its program's full path.

    Raises:
        CarbodyWorkbenchError: the program is not there.
    """
    cmd = list(command or carbody_command())
    exe = cmd[0] if os.path.isabs(cmd[0]) else shutil.which(cmd[0])
    if not exe or not os.path.exists(exe):
        raise CarbodyWorkbenchError(
            f"carbody command not found: {cmd[0]!r} (set Preferences > carbody > CarbodyCommand or $CARBODY_COMMAND)")
    return [exe, *cmd[1:]]


def run_carbody(args, command=None):
    """Run ``carbody ARGS``; its one-line error becomes a :class:`CarbodyWorkbenchError`."""
    proc = subprocess.run([*resolve_command(command), *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        lines = [line for line in proc.stderr.strip().splitlines() if line.strip()]
        raise CarbodyWorkbenchError(lines[-1] if lines else f"carbody exited with code {proc.returncode}")
    return proc


def add_photo(doc, image_path, width_mm=5000.0, command=None):
    """An image plane showing the photo upright in the car's side plane (yz), seen from the car's
    left (nose to the left), ``width_mm`` wide; a phone photo stored on its side is turned as
    its EXIF orientation says (``carbody photo-plane`` places it)."""
    placement = json.loads(run_carbody(["photo-plane", os.path.abspath(image_path), "--width", f"{float(width_mm):g}"],
                                       command).stdout)
    plane = _new_photo(doc, image_path)
    place_photo(plane, placement)
    return plane


def _new_photo(doc, image_path):
    """An image plane of the photo. The document keeps its own copy of the picture, so the file
    it came from is kept too (``SourcePhoto``), to find the plane again."""
    plane = doc.addObject("Image::ImagePlane", "Photo")
    plane.addProperty("App::PropertyPath", "SourcePhoto", "carbody", "the photo file this plane shows")
    plane.SourcePhoto = os.path.abspath(image_path)
    plane.ImageFile = os.path.abspath(image_path)
    return plane


def place_photo(plane, placement):
    """Put an image plane where ``placement`` says (``carbody photo-plane``'s JSON, or a fit
    report's ``photo_plane``: centre, the stored picture's axes and size, mm)."""
    x, y = FreeCAD.Vector(*placement["x_axis"]), FreeCAD.Vector(*placement["y_axis"])
    z, c = x.cross(y), FreeCAD.Vector(*placement["centre_mm"])
    plane.Placement = FreeCAD.Placement(FreeCAD.Matrix(x.x, y.x, z.x, c.x, x.y, y.y, z.y, c.y,
                                                       x.z, y.z, z.z, c.z, 0, 0, 0, 1))
    plane.XSize, plane.YSize = placement["width_mm"], placement["height_mm"]
    plane.Document.recompute()


def photo_camera(placement):
    """The 3D view's camera that sees the car as the photo did (``placement`` as for
    :func:`place_photo`): a dict with ``rotation`` (x along the upright picture's right, y up,
    z back toward the viewer), and for a camera close by (``eye_mm`` in the placement)
    ``position`` (its eye) and ``height_angle`` (radians, the picture's height with a margin);
    else those two are None (orthographic: any distance along the view)."""
    right, up = FreeCAD.Vector(*placement["right"]), FreeCAD.Vector(*placement["up"])
    back = right.cross(up)
    rotation = FreeCAD.Rotation(FreeCAD.Matrix(right.x, up.x, back.x, 0, right.y, up.y, back.y, 0,
                                               right.z, up.z, back.z, 0, 0, 0, 0, 1))
    if placement.get("eye_mm") is None:
        return {"rotation": rotation, "position": None, "height_angle": None}
    eye, centre = FreeCAD.Vector(*placement["eye_mm"]), FreeCAD.Vector(*placement["centre_mm"])
    y_along_up = abs(FreeCAD.Vector(*placement["y_axis"]).dot(up)) > 0.5
    height = placement["height_mm"] if y_along_up else placement["width_mm"]
    # the picture's centre may sit off the camera's axis (a turned camera): reach past it
    offset = abs((centre - eye).dot(up))
    return {"rotation": rotation, "position": eye,
            "height_angle": 2.0 * math.atan(1.1 * (height / 2 + offset) / abs((centre - eye).dot(back)))}


def match_faces(faces, entries):
    """For each FreeCAD face, the index of its entry in a carbody face listing (``centre``s)."""
    return _nearest([FreeCAD.Vector(*e["centre"]) for e in entries], [f.CenterOfMass for f in faces])


def _nearest(centres, targets):
    """Greedy nearest assignment: for each target centre, the index of the closest free centre."""
    free = set(range(len(centres)))
    out = []
    for t in targets:
        best = min(free, key=lambda i: (centres[i] - t).Length)
        free.remove(best)
        out.append(best)
    return out


def import_step_parts(doc, step_path, group_name, command=None):
    """Read a carbody STEP file into ``doc``: one Part object per curve, or per body region.

    Returns:
        the group holding the new objects.
    """
    listing = json.loads(run_carbody(["parts", step_path, "--json"], command).stdout)
    shape = Part.Shape()
    shape.read(os.path.abspath(step_path))
    group = doc.addObject("App::DocumentObjectGroup", group_name)
    if listing["faces"]:
        entries, items = listing["faces"], shape.Faces
        key = "region"
    else:
        entries, items = listing["curves"], shape.Edges
        key = "name"
    if len(entries) != len(items):
        raise CarbodyWorkbenchError(f"{step_path}: FreeCAD reads {len(items)} items, carbody lists {len(entries)}")
    order = _nearest([i.CenterOfMass for i in items], [FreeCAD.Vector(*e["centre"]) for e in entries])
    parts = {}
    for entry, i in zip(entries, order):
        parts.setdefault(entry[key], []).append(items[i])
    for name, shapes in parts.items():
        obj = doc.addObject("Part::Feature", name)
        obj.Label = name
        # A region's two mirror halves need not touch: a compound holds them either way; the
        # sewn shell itself is the BodyShell object below.
        obj.Shape = shapes[0] if len(shapes) == 1 else Part.Compound(shapes)
        group.addObject(obj)
    if key == "region":
        whole = doc.addObject("Part::Feature", f"{group_name}Shell")
        whole.Shape = shape
        group.addObject(whole)
    doc.recompute()
    return group


def reconstruct_args(image, keypoints, out_dir, view=None, wheelbase_mm=None):
    """The arguments of the ``carbody reconstruct`` run behind :func:`reconstruct`."""
    args = ["reconstruct", os.path.abspath(image), "--keypoints", os.path.abspath(keypoints), "-o",
            os.path.abspath(out_dir)]
    if view is not None:
        args += ["--view", f"{float(view):g}"]
    if wheelbase_mm is not None:
        args += ["--wheelbase", f"{float(wheelbase_mm):g}"]
    return args


def reconstruct(doc, image, keypoints, out_dir, view=None, wheelbase_mm=None, command=None):
    """Run ``carbody reconstruct`` (waiting for it: the GUI command runs it in a QProcess
    instead) and bring the car into ``doc`` (:func:`import_reconstruction`).

    Returns:
        (wireframe group, body group, report dict).
    """
    run_carbody(reconstruct_args(image, keypoints, out_dir, view, wheelbase_mm), command)
    return import_reconstruction(doc, image, out_dir, command)


def import_reconstruction(doc, image, out_dir, command=None):
    """A ``carbody reconstruct`` folder into ``doc``: the car as parametric objects
    (:func:`import_car`) and the photo lined up with the fitted camera.

    Returns:
        (wireframe group, body group, report dict).
    """
    wire, body = import_car(doc, os.path.join(out_dir, "wireframe.step"), command)
    with open(os.path.join(out_dir, "report.json")) as f:
        report = json.load(f)
    if image:
        line_up_photo(doc, image, report)
    return wire, body, report


def import_car(doc, wireframe_path, command=None):
    """A wireframe file (carbody's STEP or JSON, or a STEP saved by FreeCAD, CadQuery or build123d
    with the curves named) into ``doc`` as parametric objects (:func:`carbody_wb.model.add_car`).

    Returns:
        (wireframe group, body group).
    """
    import tempfile

    from carbody_wb import model

    with tempfile.TemporaryDirectory(prefix="carbody-fc-") as tmp:
        path = os.path.join(tmp, "wire.json")
        run_carbody(["wireframe", os.path.abspath(wireframe_path), "-o", path], command)
        with open(path) as f:
            wire_json = json.load(f)
    return model.add_car(doc, wire_json)


def line_up_photo(doc, image, report):
    """Stand the photo's image plane (added if the document has none of it) where the fit
    says: behind the car, square to the fitted camera, so that looking along it (from its eye,
    for a camera close by) the wireframe lies on the photo. Returns the plane."""
    placement = report["fit"].get("photo_plane")
    if placement is None:
        return None
    path = os.path.abspath(image)
    planes = [o for o in doc.Objects if o.TypeId == "Image::ImagePlane" and getattr(o, "SourcePhoto", None) == path]
    plane = planes[0] if planes else _new_photo(doc, path)
    place_photo(plane, placement)
    return plane


def summary(out_dir):
    """The reconstruction's ``summary.txt`` (view, camera, residuals, expected and, with a
    truth, real keypoint errors, body checks): what the report view shows after a run."""
    with open(os.path.join(out_dir, "summary.txt")) as f:
        return f.read()
