"""carbody inside FreeCAD, without the GUI: run the ``carbody`` command, bring its results in.

FreeCAD has its own OCCT build, so carbody runs as a separate process, found as
:func:`carbody_command` says. A reconstruction comes in as parametric objects
(:mod:`carbody_wb.model`: curves with editable poles, a body recomputed from them); plain STEP
files as named Part objects (:func:`import_step_parts`, body regions in their colours), their
curve and region names from ``carbody parts FILE --json``, matched to the shapes FreeCAD reads by
position, so the import does not depend on the order a STEP reader lists things in.
:class:`CarbodyProcess` runs the command in a ``QProcess`` and :class:`ReconstructJob` a whole
reconstruction, so FreeCAD stays responsive while it runs.
"""
import json
import math
import os
import shlex
import shutil
import subprocess
import tempfile

import FreeCAD
import Part

PARAM_PATH = "User parameter:BaseApp/Preferences/Mod/carbody"


class CarbodyWorkbenchError(Exception):
    """A one-line reason the workbench could not do what was asked."""


#: The workbench's own folder, symlinks resolved (a link in FreeCAD's Mod/ to a checkout).
WORKBENCH_DIR = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))

#: Names a project's virtual environment goes by.
VENV_NAMES = (".venv", "venv")

#: Where a virtual environment keeps its console scripts (POSIX, Windows).
VENV_SCRIPTS = (os.path.join("bin", "carbody"), os.path.join("Scripts", "carbody.exe"))


def carbody_command(workbench_dir=None, path=None):
    """The carbody command as an argument list, the first of: ``$CARBODY_COMMAND``; the
    preference (``CarbodyCommand``, set with the **carbody command…** button); the ``carbody`` of
    the virtual environment the workbench came from (:func:`venv_carbody`: the one it was
    installed in, or the checkout it was linked or copied from); ``carbody`` on ``path``
    (default ``$PATH``); else ``["carbody"]`` (running it then says in one line that it is not
    found).

    Args:
        workbench_dir: where the venv is looked for (default: the workbench's real folder).
        path: the search path for ``carbody`` (default ``$PATH``).
    """
    text = os.environ.get("CARBODY_COMMAND") or FreeCAD.ParamGet(PARAM_PATH).GetString("CarbodyCommand", "")
    if text.strip():
        return shlex.split(text)
    found = venv_carbody(workbench_dir) or shutil.which("carbody", path=path)
    return [found or "carbody"]


def venv_carbody(start=None):
    """The ``carbody`` program of the virtual environment the workbench came from: the one it
    lies in (installed with ``pip install carbody``: a folder above it holds ``pyvenv.cfg``), or
    a ``.venv`` or ``venv`` beside it (a checkout set up by ``make``). Looked for in ``bin``
    (``Scripts`` on Windows) of ``start`` (default :data:`WORKBENCH_DIR`; a link is followed to
    where it points) and of every folder above it; None if none."""
    here = os.path.realpath(start or WORKBENCH_DIR)
    while True:
        own = [""] if os.path.isfile(os.path.join(here, "pyvenv.cfg")) else []
        for venv in own + list(VENV_NAMES):
            for script in VENV_SCRIPTS:
                candidate = os.path.join(here, venv, script)
                if os.path.isfile(candidate) and os.access(candidate, os.X_OK):
                    return candidate
        parent = os.path.dirname(here)
        if parent == here:
            return None
        here = parent


def set_carbody_command(text):
    """Store the preference :func:`carbody_command` reads (empty: look for it again)."""
    FreeCAD.ParamGet(PARAM_PATH).SetString("CarbodyCommand", text)


def resolve_command(command=None):
    """``command`` (default :func:`carbody_command`) with its program's full path, as an argument list.

    Raises:
        CarbodyWorkbenchError: the program is not there.
    """
    cmd = list(command or carbody_command())
    exe = cmd[0] if os.path.isabs(cmd[0]) else shutil.which(cmd[0])
    if not exe or not os.path.exists(exe):
        raise CarbodyWorkbenchError(
            f"carbody command not found: {cmd[0]!r} (put carbody on PATH, or set it with the "
            "'carbody command...' button or $CARBODY_COMMAND)")
    return [exe, *cmd[1:]]


#: How ``carbody reconstruct --progress`` starts the line it writes as each stage starts.
STAGE_PREFIX = "carbody: stage "


def last_error_line(stderr, code):
    """The one line a failed carbody run says why (its last non-empty stderr line that is not a
    stage line)."""
    lines = [line for line in (stderr or "").strip().splitlines() if line.strip() and not line.startswith(STAGE_PREFIX)]
    return lines[-1] if lines else f"carbody exited with code {code}"


def run_carbody(args, command=None):
    """Run ``carbody ARGS`` and wait; its one-line error becomes a :class:`CarbodyWorkbenchError`."""
    proc = subprocess.run([*resolve_command(command), *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise CarbodyWorkbenchError(last_error_line(proc.stderr, proc.returncode))
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
    """Read a carbody STEP file into ``doc``: one Part object per curve, or per body region in
    the region's colour (``RegionColour``, and the shape's colour in the GUI), plus the sewn
    shell (``<group_name>Shell``).

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
    parts, colours = {}, {}
    for entry, i in zip(entries, order):
        parts.setdefault(entry[key], []).append(items[i])
        if entry.get("colour"):
            colours.setdefault(entry[key], tuple(float(c) for c in entry["colour"]))
    for name, shapes in parts.items():
        obj = doc.addObject("Part::Feature", name)
        obj.Label = name
        # A region's two mirror halves need not touch: a compound holds them either way; the
        # sewn shell itself is the BodyShell object below.
        obj.Shape = shapes[0] if len(shapes) == 1 else Part.Compound(shapes)
        if name in colours:
            colour_region(obj, colours[name])
        group.addObject(obj)
    if key == "region":
        whole = doc.addObject("Part::Feature", f"{group_name}Shell")
        whole.Shape = shape
        group.addObject(whole)
    doc.recompute()
    return group


def colour_region(obj, rgb):
    """Give a region's Part object its colour: kept as ``RegionColour`` (the document remembers
    it without a GUI) and shown as the shape's colour when FreeCAD has its GUI."""
    if not hasattr(obj, "RegionColour"):
        obj.addProperty("App::PropertyColor", "RegionColour", "carbody", "the region's colour in carbody's STEP file")
    obj.RegionColour = tuple(rgb)
    if FreeCAD.GuiUp and getattr(obj, "ViewObject", None) is not None:
        obj.ViewObject.ShapeColor = tuple(rgb)


def reconstruct_args(image, keypoints, out_dir, view=None, wheelbase_mm=None):
    """The arguments of ``carbody reconstruct`` for a photo and its keypoints (with a stage line
    on stderr as each stage starts: ``--progress``)."""
    args = ["reconstruct", os.path.abspath(image), "--keypoints", os.path.abspath(keypoints),
            "-o", os.path.abspath(out_dir), "--progress"]
    if view is not None:
        args += ["--view", f"{float(view):g}"]
    if wheelbase_mm is not None:
        args += ["--wheelbase", f"{float(wheelbase_mm):g}"]
    return args


def reconstruct(doc, image, keypoints, out_dir, view=None, wheelbase_mm=None, command=None):
    """Run ``carbody reconstruct`` and wait (the macro, headless), then bring the car into
    ``doc`` (:func:`import_reconstruction`); the GUI command runs :class:`ReconstructJob` instead.

    Returns:
        (wireframe group, body group, report dict).
    """
    run_carbody(reconstruct_args(image, keypoints, out_dir, view, wheelbase_mm), command)
    return import_reconstruction(doc, image, out_dir, command)


def import_reconstruction(doc, image, out_dir, command=None, wire_json=None, surfaced=None):
    """A ``carbody reconstruct`` folder into ``doc``: the car as parametric objects
    (:func:`import_car`) and the photo lined up with the fitted camera.

    Args:
        image: the photo (None: no photo plane).
        wire_json: the folder's wireframe as wireframe JSON data, already read
            (:class:`ReconstructJob` reads it; default: read it now).
        surfaced: its body as ``carbody surface`` makes it, already made (:func:`read_surfaced`;
            :class:`ReconstructJob` makes it; default: the body's first recompute makes it).
    Returns:
        (wireframe group, body group, report dict).
    """
    if wire_json is None:
        wire, body = import_car(doc, os.path.join(out_dir, "wireframe.step"), command)
    else:
        from carbody_wb import model

        wire, body = model.add_car(doc, wire_json, surfaced)
    with open(os.path.join(out_dir, "report.json")) as f:
        report = json.load(f)
    if image:
        line_up_photo(doc, image, report)
    return wire, body, report


def surface_args(wire_json_path, body_path, report_path):
    """The arguments of ``carbody surface``: a wireframe file to the sewn body (STEP) and its
    report (each face's region and colour, the folds)."""
    return ["surface", os.path.abspath(wire_json_path), "-o", os.path.abspath(body_path),
            "--report", os.path.abspath(report_path)]


def read_surfaced(body_path, report_path):
    """What ``carbody surface`` wrote (:func:`surface_args`) as (shape, report dict)."""
    with open(report_path) as f:
        report = json.load(f)
    shape = Part.Shape()
    shape.read(os.path.abspath(body_path))
    return shape, report


def wireframe_args(wireframe_path, json_path):
    """The arguments of ``carbody wireframe``: a wireframe file to wireframe JSON (both halves)."""
    return ["wireframe", os.path.abspath(wireframe_path), "-o", json_path]


def import_car(doc, wireframe_path, command=None):
    """A wireframe file (carbody's STEP or JSON, or a STEP saved by FreeCAD, CadQuery or build123d
    with the curves named) into ``doc`` as parametric objects (:func:`carbody_wb.model.add_car`).

    Returns:
        (wireframe group, body group).
    """
    from carbody_wb import model

    with tempfile.TemporaryDirectory(prefix="carbody-fc-") as tmp:
        path = os.path.join(tmp, "wire.json")
        run_carbody(wireframe_args(wireframe_path, path), command)
        with open(path) as f:
            wire_json = json.load(f)
    return model.add_car(doc, wire_json)


class CarbodyProcess:
    """One ``carbody`` run in a ``QProcess``: FreeCAD's event loop keeps running meanwhile.

    Args:
        args: the command's arguments.
        on_line: called with each line it writes on stderr (its progress), as it comes.
        on_done: called once with (ok, stdout, message): ``message`` the one-line error.
        command: the carbody command (default :func:`carbody_command`).
    """

    def __init__(self, args, on_line=None, on_done=None, command=None):
        from PySide import QtCore

        self._cmd = resolve_command(command)
        self._args = [str(a) for a in args]
        self._on_line, self._on_done = on_line, on_done
        self._stdout, self._stderr, self._partial = [], [], ""
        self._finished = False
        self.process = QtCore.QProcess()
        self.process.setProgram(self._cmd[0])
        self.process.setArguments(self._cmd[1:] + self._args)
        self.process.readyReadStandardOutput.connect(self._read_stdout)
        self.process.readyReadStandardError.connect(self._read_stderr)
        self.process.finished.connect(self._exited)
        self.process.errorOccurred.connect(self._failed)

    def start(self):
        self.process.start()
        return self

    @property
    def running(self):
        return not self._finished

    def _read_stdout(self):
        self._stdout.append(bytes(self.process.readAllStandardOutput()).decode(errors="replace"))

    def _read_stderr(self):
        text = self._partial + bytes(self.process.readAllStandardError()).decode(errors="replace")
        *lines, self._partial = text.replace("\r", "\n").split("\n")
        for line in lines:
            if line.strip():
                self._stderr.append(line)
                if self._on_line:
                    self._on_line(line)

    def _exited(self, code, status=None):
        if self._finished:
            return
        self._read_stdout()
        self._read_stderr()
        self._finished = True
        ok = code == 0 and (status is None or int(status) == 0)
        message = "" if ok else last_error_line("\n".join(self._stderr + [self._partial]), code)
        if self._on_done:
            self._on_done(ok, "".join(self._stdout), message)

    def _failed(self, error):
        from PySide import QtCore

        if error == QtCore.QProcess.FailedToStart and not self._finished:
            self._finished = True
            if self._on_done:
                self._on_done(False, "", f"carbody command could not start: {self._cmd[0]!r}")


class ReconstructJob:
    """``carbody reconstruct``, then its wireframe read back (``carbody wireframe``, to wireframe
    JSON), then that wireframe surfaced as the parametric body's recompute surfaces it
    (``carbody surface``), one after the other in :class:`CarbodyProcess` es, FreeCAD responsive
    throughout; then ``on_done(ok, result)`` with ``result`` a dict of ``wire_json`` (the
    wireframe JSON data) and ``surfaced`` (the body, :func:`read_surfaced`), the arguments of
    :func:`import_reconstruction` that spare it any wait; or the one-line error.

    Args:
        on_progress: called with a line a person can read as each stage starts.
    """

    def __init__(self, image, keypoints, out_dir, view=None, wheelbase_mm=None, command=None,
                 on_progress=None, on_done=None):
        self.out_dir = out_dir
        self._command, self._on_progress, self._on_done = command, on_progress, on_done
        self._tmp = tempfile.TemporaryDirectory(prefix="carbody-fc-")
        self._wire_json = os.path.join(self._tmp.name, "wire.json")
        self._body = (os.path.join(self._tmp.name, "body.step"), os.path.join(self._tmp.name, "body.json"))
        self._steps = [("reconstruct", reconstruct_args(image, keypoints, out_dir, view, wheelbase_mm)),
                       ("reading the wireframe back", wireframe_args(os.path.join(out_dir, "wireframe.step"),
                                                                     self._wire_json)),
                       ("surfacing the editable body", surface_args(self._wire_json, *self._body))]
        self.current = None

    @property
    def running(self):
        return self.current is not None and self.current.running

    def start(self):
        self._next()
        return self

    def _say(self, text):
        if self._on_progress:
            self._on_progress(text)

    def _finish(self, ok, result):
        self._steps = []
        self.current = None
        self._tmp.cleanup()
        if self._on_done:
            self._on_done(ok, result)

    def _next(self):
        if not self._steps:
            try:
                with open(self._wire_json) as f:
                    wire_json = json.load(f)
                surfaced = read_surfaced(*self._body)
            except (OSError, ValueError, RuntimeError) as exc:  # (FreeCAD's reader errors are RuntimeErrors)
                self._finish(False, f"carbody wrote no wireframe or body to bring in: {exc}")
                return
            self._finish(True, {"wire_json": wire_json, "surfaced": surfaced})
            return
        key, args = self._steps.pop(0)
        if key != "reconstruct":
            self._say(key)

        def line(text):
            if text.startswith(STAGE_PREFIX):
                self._say(text[len("carbody: "):])

        def done(ok, stdout, message):
            if ok:
                self._next()
            else:
                self._finish(False, message)

        try:
            self.current = CarbodyProcess(args, line, done, self._command).start()
        except CarbodyWorkbenchError as exc:
            self._finish(False, str(exc))


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
