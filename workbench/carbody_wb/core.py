"""carbody inside FreeCAD, without the GUI: run the ``carbody`` command, bring its STEP results in.

FreeCAD has its own OCCT build, so carbody runs as a separate process (the command is set in
Preferences > carbody, parameter ``CarbodyCommand``, or ``$CARBODY_COMMAND``). Curve and region
names come from ``carbody parts FILE --json``, matched to the shapes FreeCAD reads by position,
so the import does not depend on the order a STEP reader lists things in.
"""
import json
import os
import shlex
import shutil
import struct
import subprocess

import FreeCAD
import Part

PARAM_PATH = "User parameter:BaseApp/Preferences/Mod/carbody"


class CarbodyWorkbenchError(Exception):
    """A one-line reason the workbench could not do what was asked."""


def carbody_command():
    """The carbody command as an argument list: ``$CARBODY_COMMAND`` or the preference."""
    text = os.environ.get("CARBODY_COMMAND") or FreeCAD.ParamGet(PARAM_PATH).GetString("CarbodyCommand", "carbody")
    return shlex.split(text)


def set_carbody_command(text):
    FreeCAD.ParamGet(PARAM_PATH).SetString("CarbodyCommand", text)


def run_carbody(args, command=None):
    """Run ``carbody ARGS``; its one-line error becomes a :class:`CarbodyWorkbenchError`."""
    cmd = list(command or carbody_command())
    exe = cmd[0] if os.path.isabs(cmd[0]) else shutil.which(cmd[0])
    if not exe or not os.path.exists(exe):
        raise CarbodyWorkbenchError(
            f"carbody command not found: {cmd[0]!r} (set Preferences > carbody > CarbodyCommand or $CARBODY_COMMAND)")
    proc = subprocess.run([exe, *cmd[1:], *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        lines = [line for line in proc.stderr.strip().splitlines() if line.strip()]
        raise CarbodyWorkbenchError(lines[-1] if lines else f"carbody exited with code {proc.returncode}")
    return proc


def image_size(path):
    """(width, height) in pixels of a PNG or JPEG file, read from its header."""
    with open(path, "rb") as f:
        head = f.read(26)
        if head[:8] == b"\x89PNG\r\n\x1a\n":
            return struct.unpack(">II", head[16:24])
        if head[:2] == b"\xff\xd8":
            f.seek(2)
            while True:
                marker = f.read(2)
                if len(marker) < 2 or marker[0] != 0xFF:
                    break
                length = struct.unpack(">H", f.read(2))[0]
                if 0xC0 <= marker[1] <= 0xCF and marker[1] not in (0xC4, 0xC8, 0xCC):
                    h, w = struct.unpack(">xHH", f.read(5))
                    return w, h
                f.seek(length - 2, 1)
    raise CarbodyWorkbenchError(f"{path}: not a PNG or JPEG image")


def add_photo(doc, image_path, width_mm=5000.0):
    """An image plane showing the photo in the car's side plane (yz), ``width_mm`` wide."""
    w, h = image_size(image_path)
    plane = doc.addObject("Image::ImagePlane", "Photo")
    plane.ImageFile = os.path.abspath(image_path)
    plane.XSize = width_mm
    plane.YSize = width_mm * h / w
    plane.Placement = FreeCAD.Placement(FreeCAD.Vector(0, 0, 0), FreeCAD.Rotation(FreeCAD.Vector(0, 1, 0), 90))
    doc.recompute()
    return plane


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


def reconstruct(doc, image, keypoints, out_dir, view=None, wheelbase_mm=None, command=None):
    """Run ``carbody reconstruct`` and bring the wireframe and body into ``doc``.

    Returns:
        (wireframe group, body group, report dict).
    """
    args = ["reconstruct", image, "--keypoints", keypoints, "-o", out_dir]
    if view is not None:
        args += ["--view", f"{float(view):g}"]
    if wheelbase_mm is not None:
        args += ["--wheelbase", f"{float(wheelbase_mm):g}"]
    run_carbody(args, command)
    wire = import_step_parts(doc, os.path.join(out_dir, "wireframe.step"), "Wireframe", command)
    body = import_step_parts(doc, os.path.join(out_dir, "body.step"), "Body", command)
    with open(os.path.join(out_dir, "report.json")) as f:
        report = json.load(f)
    return wire, body, report


def summary(out_dir):
    """The reconstruction's ``summary.txt`` (view, camera, residuals, expected and, with a
    truth, real keypoint errors, body checks): what the report view shows after a run."""
    with open(os.path.join(out_dir, "summary.txt")) as f:
        return f.read()
