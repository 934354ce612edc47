"""The FreeCAD workbench and macro, run headless in FreeCAD 0.20's freecadcmd (a real FreeCAD)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.conftest import REPO

WORKBENCH = REPO / "workbench"
pytestmark = pytest.mark.freecad


def run_freecad(script: str, tmp_path: Path, env: dict | None = None) -> dict:
    """Run a Python script in freecadcmd; the script prints one line ``RESULT <json>``."""
    path = tmp_path / "fc_script.py"
    path.write_text(f"import sys\nsys.path.insert(0, {str(WORKBENCH)!r})\n" + script)
    proc = subprocess.run(["freecadcmd", str(path)], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "CARBODY_COMMAND": f"{sys.executable} -m carbody", **(env or {})})
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    raise AssertionError(f"freecadcmd gave no result:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")


def test_addon_layout_for_the_addon_manager():
    root = ET.parse(WORKBENCH / "package.xml").getroot()
    ns = {"p": "https://wiki.freecad.org/Package_Metadata"}
    assert root.find("p:name", ns).text == "carbody"
    assert root.find("p:content/p:workbench/p:classname", ns).text == "CarbodyWorkbench"
    assert (WORKBENCH / root.find("p:icon", ns).text).is_file()
    assert (WORKBENCH / root.find("p:content/p:macro/p:file", ns).text).is_file()
    text = (WORKBENCH / "carbody_wb" / "commands.py").read_text()
    for icon in ("load_photo.svg", "load_keypoints.svg", "reconstruct.svg"):
        assert icon in text and (WORKBENCH / "Resources" / "icons" / icon).is_file()
    assert "class CarbodyWorkbench" in (WORKBENCH / "InitGui.py").read_text()


def test_a_wireframe_comes_into_freecad_as_parts_named_by_curve(tmp_path, topology):
    from carbody.templates import templates_dir

    step = templates_dir() / "volvo_v60.step"
    result = run_freecad(f"""
import json, FreeCAD
from carbody_wb import core
doc = FreeCAD.newDocument("t")
group = core.import_step_parts(doc, {str(step)!r}, "Wireframe")
objs = group.Group
print("RESULT " + json.dumps({{
    "labels": [o.Label for o in objs],
    "valid": all(o.Shape.isValid() for o in objs),
    "edges": sum(len(o.Shape.Edges) for o in objs),
    "first": [round(v, 3) for v in objs[0].Shape.Edges[0].Vertexes[0].Point],
}}))
""", tmp_path)
    assert result["labels"] == [c.name for c in topology.curves]
    assert result["valid"] and result["edges"] == 70
    from carbody.wireframe import read_wireframe

    first = read_wireframe(step).control_points[[0, 3]]
    assert any(abs(p - result["first"]).max() < 1e-3 for p in first)


def test_the_photo_becomes_an_upright_image_plane_with_its_aspect(tmp_path):
    """Loaded before any fit, the photo stands in the car's side plane as the left side is seen
    (the picture's right toward the rear, +y; its up, +z) — a phone photo stored on its side
    (EXIF orientation 6) too, turned upright."""
    import cv2

    for name in ("car.png", "car.jpg"):
        cv2.imwrite(str(tmp_path / name), np.full((300, 800, 3), 200, np.uint8))
    exif = Image.Exif()
    exif[0x0112] = 6  # stored 300 wide, 800 high: upright 800 × 300
    Image.new("RGB", (300, 800)).save(tmp_path / "phone.jpg", exif=exif)
    result = run_freecad(f"""
import json, FreeCAD
from carbody_wb import core
doc = FreeCAD.newDocument("t")
planes = [core.add_photo(doc, {str(tmp_path)!r} + "/" + n, 4000.0) for n in ("car.png", "car.jpg", "phone.jpg")]
def axis(p, v):
    return list(p.Placement.Rotation.multVec(FreeCAD.Vector(*v)))
print("RESULT " + json.dumps([[float(p.XSize), float(p.YSize), axis(p, (1, 0, 0)), axis(p, (0, 1, 0))]
                              for p in planes]))
""", tmp_path)
    expected = [([4000.0, 1500.0], [0, 1, 0], [0, 0, 1])] * 2 + [
        # stored right points down the upright picture, stored up toward the rear
        ([1500.0, 4000.0], [0, 0, -1], [0, 1, 0])]
    for (size, x, y), got in zip(expected, result, strict=True):
        assert got[:2] == size and np.allclose(got[2], x) and np.allclose(got[3], y)


def test_a_missing_carbody_command_is_one_clear_line(tmp_path):
    result = run_freecad("""
import json, FreeCAD
from carbody_wb import core
try:
    core.run_carbody(["library"], ["/nonexistent/carbody"])
    print("RESULT " + json.dumps("no error"))
except core.CarbodyWorkbenchError as exc:
    print("RESULT " + json.dumps(str(exc)))
""", tmp_path)
    assert "carbody command not found" in result and "\n" not in result


def test_a_body_comes_into_freecad_as_parts_named_by_region(tmp_path, topology):
    from carbody.templates import templates_dir
    from tests.conftest import run_cli

    body_step = tmp_path / "body.step"
    run_cli("surface", str(templates_dir() / "volkswagen_golf_mk7.step"), "-o", str(body_step), check=True)
    listing = json.loads(run_cli("parts", str(body_step), "--json", check=True).stdout)
    result = run_freecad(f"""
import json, FreeCAD
from carbody_wb import core
doc = FreeCAD.newDocument("t")
group = core.import_step_parts(doc, {str(body_step)!r}, "Body")
objs = {{o.Label: o for o in group.Group}}
shell = objs.pop("BodyShell")
print("RESULT " + json.dumps({{
    "colours": {{n: list(o.RegionColour)[:3] for n, o in objs.items()}},
    "regions": sorted(objs),
    "valid": all(o.Shape.isValid() for o in objs.values()) and shell.Shape.isValid(),
    "faces": sum(len(o.Shape.Faces) for o in objs.values()),
    "shell_faces": len(shell.Shape.Faces),
}}))
""", tmp_path)
    assert result["regions"] == sorted(r.name for r in topology.regions)
    assert result["valid"]
    assert result["faces"] == result["shell_faces"] == len(listing["faces"])
    # each region keeps the colour the STEP file gives it (FreeCAD stores colours in 8 bits)
    from carbody.surface.body import region_colour

    for region, rgb in result["colours"].items():
        assert np.allclose(rgb, region_colour(region), atol=1 / 255), region


def test_reconstruct_runs_in_a_qprocess_with_its_progress_while_freecad_keeps_running(tmp_path):
    """The GUI's Reconstruct runs carbody in a QProcess: FreeCAD's event loop keeps turning (a
    timer ticks all along), each stage line comes as the command writes it, a failure ends in
    its one line, and the whole job hands over the wireframe read back as wireframe JSON and
    the editable body surfaced from it (its shape read, its report)."""
    fake = tmp_path / "fake_carbody.py"
    fake.write_text("import sys, time\n"
                    "if sys.argv[1] == 'wireframe':\n"
                    "    open(sys.argv[4], 'w').write('{\"file\": \"' + sys.argv[2].rsplit('/', 1)[-1] + '\"}'); sys.exit(0)\n"
                    "if sys.argv[1] == 'surface':  # a box for a body, from the wireframe JSON read back\n"
                    "    import json, shutil\n"
                    "    shutil.copy(sys.argv[0].replace('fake_carbody.py', 'box.step'), sys.argv[4])\n"
                    "    json.dump({'faces': [], 'folds': [], 'from': json.load(open(sys.argv[2]))}, open(sys.argv[6], 'w'))\n"
                    "    sys.exit(0)\n"
                    "if sys.argv[1] == 'fail':\n"
                    "    print('carbody reconstruct: error: the keypoints are coincident', file=sys.stderr); sys.exit(2)\n"
                    "for stage in ('view', 'fit', 'surfaces', 'write'):\n"
                    "    print(f'carbody: stage {stage}', file=sys.stderr, flush=True); time.sleep(0.3)\n"
                    "print('{\"ok\": true}')\n")
    result = run_freecad(f"""
import json, sys, time, FreeCAD
from PySide import QtCore
import Part
from carbody_wb import core
Part.makeBox(10, 20, 30).exportStep({str(tmp_path / "box.step")!r})
app = QtCore.QCoreApplication.instance() or QtCore.QCoreApplication([])
command = [{sys.executable!r}, {str(fake)!r}]
events = []
ticks = [0]
timer = QtCore.QTimer(); timer.timeout.connect(lambda: ticks.__setitem__(0, ticks[0] + 1)); timer.start(50)
def run(args):
    loop = QtCore.QEventLoop()
    out = {{}}
    def done(ok, stdout, message):
        out.update(ok=ok, stdout=stdout, message=message); loop.quit()
    job = core.CarbodyProcess(args, lambda line: events.append([round(time.monotonic(), 2), line, ticks[0]]), done, command).start()
    started = time.monotonic()
    loop.exec_()
    out["seconds"] = time.monotonic() - started
    return out
good = run(["reconstruct"])
bad = run(["fail"])
# the whole job: reconstruct, then its wireframe read back as wireframe JSON, one after the other
loop = QtCore.QEventLoop()
said, finished = [], {{}}
def job_done(ok, result):
    shape, report = result["surfaced"]
    finished.update(ok=ok, wire_json=result["wire_json"], faces=len(shape.Faces), report=report); loop.quit()
core.ReconstructJob("car.png", "car.json", {str(tmp_path / "out")!r}, command=command, on_progress=said.append,
                    on_done=job_done).start()
loop.exec_()
print("RESULT " + json.dumps({{"good": good, "bad": bad, "events": events, "ticks": ticks[0], "said": said,
                               "job": finished}}))
""", tmp_path, env={"CARBODY_COMMAND": ""})
    good, bad, events = result["good"], result["bad"], result["events"]
    assert good["ok"] and json.loads(good["stdout"]) == {"ok": True}
    stages = events[:4]
    assert [e[1] for e in stages] == [f"carbody: stage {s}" for s in ("view", "fit", "surfaces", "write")]
    # the lines came as they were written, and the timer ticked in between: nothing blocked
    assert stages[-1][0] - stages[0][0] > 0.6 and stages[-1][2] - stages[0][2] >= 8
    assert not bad["ok"] and bad["message"] == "carbody reconstruct: error: the keypoints are coincident"
    job = result["job"]
    assert job["ok"] and job["wire_json"] == {"file": "wireframe.step"} and job["faces"] == 6
    assert job["report"] == {"faces": [], "folds": [], "from": {"file": "wireframe.step"}}
    assert result["said"] == ["stage view", "stage fit", "stage surfaces", "stage write", "reading the wireframe back",
                              "surfacing the editable body"]


#: The real carbody, each call logged with its start and end (time.monotonic: one clock per
#: machine), so the test can tell which ran in the job's QProcesses and when.
LOGGED_CARBODY = """
import os, subprocess, sys, time
start = time.monotonic()
code = subprocess.call([sys.executable, "-m", "carbody", *sys.argv[1:]])
with open(os.environ["CARBODY_CALL_LOG"], "a") as log:
    log.write(f"{sys.argv[1]} {start} {time.monotonic()}\\n")
sys.exit(code)
"""

#: Run in FreeCAD's GUI: the Reconstruct command as a user runs it (photo and keypoints chosen,
#: the output folder picked in the dialog), a 50 ms timer ticking all along; when the car is in,
#: what the GUI shows is written to RESULT_PATH.
GUI_SCRIPT = """
import json, os, sys, time
sys.path.insert(0, {workbench!r})
import FreeCAD, FreeCADGui
from PySide import QtCore, QtGui
from carbody_wb import commands, core
commands.register()
params = FreeCAD.ParamGet(core.PARAM_PATH)
params.SetString("LastImage", {image!r})
params.SetString("LastKeypoints", {keypoints!r})
QtGui.QFileDialog.getExistingDirectory = staticmethod(lambda *args, **kwargs: {out!r})
window = FreeCADGui.getMainWindow()
said, ticks = [], []
window.statusBar().messageChanged.connect(lambda text: said.append([time.monotonic(), text]) if text else None)
timer = QtCore.QTimer()
timer.timeout.connect(lambda: ticks.append(time.monotonic()))
timer.start(50)

def collect():
    doc = FreeCAD.ActiveDocument
    body = doc.getObject("CarBody")
    regions = [o for o in doc.getObject("Body").Group if o is not body]
    report = window.findChild(QtGui.QTextEdit, "Report view")
    with open({result!r}, "w") as f:
        json.dump({{"said": said, "ticks": ticks,
                    "face_colours": [list(c)[:3] for c in body.FaceColours],
                    "shown_colours": [list(c)[:3] for c in body.ViewObject.DiffuseColor],
                    "faces": len(body.Shape.Faces), "status": body.Status,
                    "regions": {{o.Label: [list(o.Colour)[:3], list(o.ViewObject.ShapeColor)[:3]] for o in regions}},
                    "curves": len(doc.getObject("Wireframe").Group),
                    "report_view": report.toPlainText() if report is not None else None}}, f)
    # an edit afterwards surfaces the body again (the body made in the background served once)
    from carbody_wb import model
    model.move_junction(doc, "roof_front_corner", (0, 0, 30))
    doc.recompute()
    os._exit(0)

def check():
    if said and said[-1][1].startswith("carbody: done"):
        poll.stop()
        QtCore.QTimer.singleShot(1000, collect)  # the colours are painted after Part's own update

def give_up():
    with open({result!r}, "w") as f:
        json.dump({{"said": said, "timed_out": True}}, f)
    os._exit(3)

FreeCADGui.runCommand("Carbody_Reconstruct")
poll = QtCore.QTimer()
poll.timeout.connect(check)
poll.start(100)
QtCore.QTimer.singleShot(180000, give_up)
"""


@pytest.mark.skipif(not (shutil.which("xvfb-run") and shutil.which("freecad")),
                    reason="needs FreeCAD's GUI (freecad-python3) and xvfb-run")
def test_the_guis_reconstruct_runs_in_the_background_and_brings_the_car_in_coloured(tmp_path):
    """FreeCAD's GUI (under xvfb-run), the Reconstruct command clicked on the shipped example, the
    real carbody run: the stages come into the status bar and the report view while the event
    loop keeps turning; the job reads the wireframe back and surfaces the editable body in the
    background, so bringing the car in runs no carbody (no wait in FreeCAD's own thread); the
    body's faces and each region object show their region's colour."""
    from carbody.pipeline import STAGES

    out = tmp_path / "out"
    logged, log, result = tmp_path / "logged_carbody.py", tmp_path / "calls.log", tmp_path / "gui.json"
    logged.write_text(LOGGED_CARBODY)
    script = tmp_path / "gui_reconstruct.py"
    script.write_text(GUI_SCRIPT.format(workbench=str(WORKBENCH), image=str(REPO / "examples" / "car.png"),
                                        keypoints=str(REPO / "examples" / "car_keypoints.json"), out=str(out),
                                        result=str(result)))
    env = {**os.environ, "CARBODY_COMMAND": f"{sys.executable} {logged}", "CARBODY_CALL_LOG": str(log),
           "QTWEBENGINE_DISABLE_SANDBOX": "1", "HOME": str(tmp_path / "home")}
    proc = subprocess.run(["xvfb-run", "-a", "freecad", str(script)], capture_output=True, text=True,
                          timeout=300, env=env, cwd=tmp_path)
    assert result.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    r = json.loads(result.read_text())
    said = [text for _, text in r["said"]]
    assert not r.get("timed_out"), said
    names = (*STAGES, "write")
    stages = [f"carbody: stage {name} ({k}/{len(names)})" for k, name in enumerate(names, 1)]
    # (FreeCAD's console shows each report-view line in the status bar too: a line may come twice)
    assert list(dict.fromkeys(t for t in said if t in stages)) == stages, said
    assert "carbody: reading the wireframe back" in said and "carbody: surfacing the editable body" in said
    assert said[-1].startswith("carbody: done"), said
    for line in stages + ["carbody: reading the wireframe back"]:
        assert line in r["report_view"]
    # the event loop turned all along: ticks between the first stage and the last job step
    times = {}
    for t, text in r["said"]:
        times.setdefault(text, t)
    ticks = np.array(r["ticks"])
    first, last = times[stages[0]], times["carbody: surfacing the editable body"]
    assert np.count_nonzero((ticks > first) & (ticks < last)) >= 0.5 * (last - first) / 0.05
    # carbody ran three times, all in the job's QProcesses: bringing the car in ran none
    calls = [line.split() for line in log.read_text().splitlines()]
    assert [c[0] for c in calls] == ["reconstruct", "wireframe", "surface", "surface"]
    # (time.monotonic is one clock per machine): the job's surface ended before the car came in,
    # the next one is the edit's, after it
    assert float(calls[2][2]) < times["carbody: bringing the car in ..."] < times[said[-1]] < float(calls[3][1])
    # the colours: every face painted its region's, every region object shows its own
    from carbody.surface.body import region_colour

    assert r["faces"] == len(r["face_colours"]) == len(r["shown_colours"]) and r["status"].startswith("valid")
    assert np.allclose(r["shown_colours"], r["face_colours"], atol=1 / 255)
    assert len(r["regions"]) == 13 and r["curves"] == 125
    for region, (colour, shown) in r["regions"].items():
        assert np.allclose(colour, region_colour(region), atol=1 / 255) and np.allclose(shown, colour, atol=1 / 255), region


def test_the_macro_reconstructs_headless_and_the_document_matches_the_step_files(tmp_path):
    out, saved = tmp_path / "out", tmp_path / "car.FCStd"
    env = {**os.environ, "CARBODY_COMMAND": f"{sys.executable} -m carbody",
           "CARBODY_IMAGE": str(REPO / "examples" / "car.png"),
           "CARBODY_KEYPOINTS": str(REPO / "examples" / "car_keypoints.json"),
           "CARBODY_OUT": str(out), "CARBODY_VIEW": "30", "CARBODY_SAVE": str(saved)}
    proc = subprocess.run(["freecadcmd", str(WORKBENCH / "carbody_reconstruct.FCMacro")], capture_output=True,
                          text=True, timeout=600, env=env, cwd=tmp_path)
    assert saved.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    # the run's summary reaches FreeCAD's report view: how sure the fit is, keypoint by keypoint
    assert "expected 3D keypoint error" in proc.stdout + proc.stderr, proc.stdout[-2000:]
    from tests.conftest import run_cli

    curves = json.loads(run_cli("parts", str(out / "wireframe.step"), "--json", check=True).stdout)["curves"]
    faces = json.loads(run_cli("parts", str(out / "body.step"), "--json", check=True).stdout)["faces"]
    width, height = Image.open(REPO / "examples" / "car.png").size
    result = run_freecad(f"""
import json, FreeCAD
doc = FreeCAD.openDocument({str(saved)!r})
wire, body = doc.getObject("Wireframe"), doc.getObject("Body")
regions = [o for o in body.Group if o.Label != "BodyShell"]
photo = doc.getObject("Photo")
report = json.load(open({str(out / "report.json")!r}))["fit"]
eye = report["photo_plane"]["eye_mm"]
inverse = photo.Placement.inverse()
seen = {{}}
for name, p in report["keypoints_mm"].items():
    q = inverse.multVec(FreeCAD.Vector(*p))  # seen square to the plane (local z = 0) ...
    if eye is not None:  # ... or from the camera's eye
        a = inverse.multVec(FreeCAD.Vector(*eye))
        q = a + (q - a) * (a.z / (a.z - q.z))
    seen[name] = [(q.x / photo.XSize.Value + 0.5) * {width}, (0.5 - q.y / photo.YSize.Value) * {height}]
# the 3D view's camera (set by the Reconstruct command): at the eye, turned as the photo, wide
# enough to hold its four corners
import math
from carbody_wb import core
camera = core.photo_camera(report["photo_plane"])
turned = camera["rotation"].inverted()
corners = [turned.multVec(photo.Placement.multVec(FreeCAD.Vector(sx * photo.XSize.Value / 2, sy * photo.YSize.Value / 2, 0))
                          - camera["position"]) for sx in (-1, 1) for sy in (-1, 1)]
print("RESULT " + json.dumps({{
    "camera_right": list(camera["rotation"].multVec(FreeCAD.Vector(1, 0, 0))),
    "camera_at_eye": (camera["position"] - FreeCAD.Vector(*report["photo_plane"]["eye_mm"])).Length,
    "corner_angles": [math.degrees(math.atan2(abs(c.y), -c.z)) for c in corners],
    "height_angle": math.degrees(camera["height_angle"]),
    "photos": sum(o.TypeId == "Image::ImagePlane" for o in doc.Objects),
    "seen_px": seen,
    "curve_labels": sorted(o.Label for o in wire.Group),
    "edges": sum(len(o.Shape.Edges) for o in wire.Group),
    "faces": sum(len(o.Shape.Faces) for o in regions),
    "valid": all(o.Shape.isValid() for o in wire.Group + body.Group),
}}))
""", tmp_path)
    assert result["photos"] == 1 and result["valid"]
    # the photo lined up with the fitted camera: each keypoint, seen from the camera's eye, lies
    # on the photo's image plane where it was marked (to the fit's residual)
    report = json.loads((out / "report.json").read_text())["fit"]
    assert np.allclose(result["camera_right"], report["photo_plane"]["right"]) and result["camera_at_eye"] < 1e-6
    assert max(result["corner_angles"]) < result["height_angle"] / 2 < 1.2 * max(result["corner_angles"])
    marks = json.loads((REPO / "examples" / "car_keypoints.json").read_text())["keypoints"]
    names = list(report["residual_px"])
    seen = np.array([result["seen_px"][n] for n in names])
    off = np.linalg.norm(seen - np.array([marks[n] for n in names]), axis=1)
    assert np.allclose(off, [report["residual_px"][n] for n in names], atol=0.01)
    assert result["curve_labels"] == sorted(c["name"] for c in curves)
    assert result["edges"] == len(curves) == 125
    assert result["faces"] == len(faces)


def test_carbody_freecad_builds_a_document_or_says_freecad_is_missing(tmp_path):
    from tests.conftest import run_cli

    out = tmp_path / "out"
    run_cli("reconstruct", str(REPO / "examples" / "car.png"), "-k", str(REPO / "examples" / "car_keypoints.json"),
            "--view", "30", "-o", str(out), check=True)
    proc = run_cli("freecad", str(out), "-o", str(tmp_path / "car.FCStd"))
    assert proc.returncode == 0 and "125 curve objects" in proc.stdout and (tmp_path / "car.FCStd").is_file()
    missing = run_cli("freecad", str(out), "-o", str(tmp_path / "none.FCStd"), "--freecadcmd", "/no/such/freecadcmd")
    lines = missing.stderr.strip().splitlines()
    assert missing.returncode == 2 and len(lines) == 1 and "FreeCAD is not installed" in lines[0]
    assert not (tmp_path / "none.FCStd").exists()


def test_the_car_comes_in_parametric_and_the_body_follows_a_moved_junction(tmp_path, topology):
    """One freecadcmd run: a template as parametric objects (125 curves with editable poles, the
    CarBody shell and 13 coloured regions); the roof-front junction moved up 50 mm as a user
    moving one pole, its curves and mirror twin follow and the recomputed shell is valid and
    passes through the moved curves within 0.01 mm; FreeCAD's own STEP export of the curves reads
    back in carbody; a document saved and reopened still carries edits; the junction dragged far
    is one line in the report view naming the folded region and its curves."""
    from carbody.templates import templates_dir
    from carbody.wireframe import read_wireframe

    step = templates_dir() / "volvo_v60.step"
    exported, saved = tmp_path / "freecad_export.step", tmp_path / "car.FCStd"
    touched = [c.name for c in topology.curves if "roof_front_corner" in (c.start, c.end)]
    script = f"""
import json, FreeCAD, Part, Import
from carbody_wb import core, model
doc = FreeCAD.newDocument("t")
wire, body = core.import_car(doc, {str(step)!r})
shell = doc.getObject("CarBody")
curves = {{o.CurveName: o for o in wire.Group}}
out = {{"curves": len(curves), "labels_are_names": all(o.Label == n for n, o in curves.items()),
        "regions": sorted(o.Label for o in body.Group if o is not shell),
        "region_colours": len({{tuple(o.Colour) for o in body.Group if o is not shell}}),
        "faces": len(shell.Shape.Faces), "colours": len(shell.FaceColours), "status0": shell.Status,
        "valid0": shell.Shape.isValid()}}
before = curves["roof_side_1"].Poles[0]
# the user moves one pole: the end of a_pillar_2 on the roof's front corner
poles = list(curves["a_pillar_2"].Poles)
poles[3] = poles[3] + FreeCAD.Vector(0, 0, 50)
curves["a_pillar_2"].Poles = poles
ends = [curves["windshield_top"].Poles[3], curves["a_pillar_2"].Poles[3], curves["roof_side_1"].Poles[0]]
twins = [curves["windshield_top_right"].Poles[3], curves["a_pillar_2_right"].Poles[3], curves["roof_side_1_right"].Poles[0]]
out["joined"] = max((p - ends[0]).Length for p in ends)
out["mirrored"] = max((FreeCAD.Vector(-p.x, p.y, p.z) - ends[0]).Length for p in twins)
out["raised"] = ends[0].z - before.z
doc.recompute()
out["valid"] = shell.Shape.isValid() and len(shell.Shape.Shells) == 1
out["status"], out["folds"] = shell.Status, list(shell.Folds)
names = {touched!r}
far = 0.0
for n in names + [n + "_right" for n in names]:
    e = curves[n].Shape.Edges[0]
    for k in range(11):
        p = e.valueAt(e.FirstParameter + k / 10.0 * (e.LastParameter - e.FirstParameter))
        far = max(far, shell.Shape.distToShape(Part.Vertex(p))[0])
out["off_curve_mm"] = far
Import.export(wire.Group, {str(exported)!r})
doc.saveAs({str(saved)!r})
FreeCAD.closeDocument(doc.Name)
doc = FreeCAD.openDocument({str(saved)!r})
curves = {{o.CurveName: o for o in doc.Objects if hasattr(o, "CurveName")}}
model.move_junction(doc, "roof_front_corner", (0, 800, 0))  # back over the roof
out["reopened_follows"] = (curves["roof_side_1_right"].Poles[0].y - curves["a_pillar_2"].Poles[3].y)
doc.recompute()
shell = doc.getObject("CarBody")
out["far_folds"], out["far_status"] = list(shell.Folds), shell.Status
print("RESULT " + json.dumps(out))
"""
    path = tmp_path / "fc_script.py"
    path.write_text(f"import sys\nsys.path.insert(0, {str(WORKBENCH)!r})\n" + script)
    proc = subprocess.run(["freecadcmd", str(path)], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "CARBODY_COMMAND": f"{sys.executable} -m carbody"})
    lines = [line for line in proc.stdout.splitlines() if line.startswith("RESULT ")]
    assert lines, proc.stdout[-3000:] + proc.stderr[-2000:]
    r = json.loads(lines[0][len("RESULT "):])
    assert r["curves"] == 125 and r["labels_are_names"]
    assert r["regions"] == sorted(reg.name for reg in topology.regions) and r["region_colours"] == 13
    assert r["valid0"] and r["colours"] == r["faces"] and r["status0"].startswith("valid")
    assert r["joined"] < 1e-9 and r["mirrored"] < 1e-9 and r["raised"] == pytest.approx(50.0)
    assert r["valid"] and r["folds"] == [] and r["status"].startswith("valid")
    assert r["off_curve_mm"] <= 0.01
    # FreeCAD's STEP export of the curve objects (a product per object) reads back as moved,
    # and surfaces
    from tests.conftest import run_cli

    run_cli("surface", str(exported), "-o", str(tmp_path / "body.step"), check=True)
    moved = read_wireframe(exported)
    kp = moved.keypoints()["roof_front_corner"]
    assert kp[2] == pytest.approx(read_wireframe(step).keypoints()["roof_front_corner"][2] + 50.0)
    assert abs(r["reopened_follows"]) < 1e-9
    assert r["far_folds"] and r["far_status"] == r["far_folds"][0]
    assert r["far_status"].startswith("region ") and " folds: " in r["far_status"] and "_" in r["far_status"]
    # the report view: one line per folded region
    report_view = [line for line in (proc.stdout + proc.stderr).replace("\t", "\n").splitlines()
                   if line.startswith("carbody: region ")]
    assert report_view and report_view[0] == "carbody: " + r["far_folds"][0]


def test_freecad_shows_the_curve_names_carbody_writes(tmp_path, templates):
    """FreeCAD's STEP import (as its GUI does, a part per product) names every curve object."""
    from carbody.wireframe import write_wireframe

    _, wf = templates[0]
    path = write_wireframe(tmp_path / "car.step", wf, both_halves=True)
    result = run_freecad(f"""
import json, FreeCAD, Import
FreeCAD.ParamGet("User parameter:BaseApp/Preferences/Mod/Import").SetBool("UseLinkGroup", False)
doc = FreeCAD.newDocument("t")
Import.insert({str(path)!r}, "t")
print("RESULT " + json.dumps(sorted(o.Label for o in doc.Objects if o.TypeId == "Part::Feature")))
""", tmp_path)
    assert result == sorted(n for n, _ in wf.named_curves(both_halves=True))


def test_the_carbody_command_is_found_in_its_order_env_preference_venv_path(tmp_path):
    """$CARBODY_COMMAND, else the preference, else the carbody of the virtual environment the
    workbench came from (the link in FreeCAD's Mod/ followed; before PATH): the one it was
    installed in, or a .venv in the checkout it was linked from; else carbody on PATH, else the
    bare name (running it then says it is not found)."""
    checkout = tmp_path / "checkout"
    (checkout / ".venv" / "bin").mkdir(parents=True)
    fake = checkout / ".venv" / "bin" / "carbody"
    fake.write_text("#!/bin/sh\necho fake\n")
    fake.chmod(0o755)
    shutil.copytree(WORKBENCH, checkout / "workbench", ignore=shutil.ignore_patterns("__pycache__"))
    mod = tmp_path / "Mod"
    mod.mkdir()
    (mod / "carbody").symlink_to(checkout / "workbench")  # FreeCAD's Mod/ -> the checkout
    on_path = tmp_path / "bin"
    on_path.mkdir()
    (on_path / "carbody").write_text("#!/bin/sh\n")
    (on_path / "carbody").chmod(0o755)
    # installed with pip into a virtual environment of any name: the workbench lies in its
    # site-packages, linked into another Mod/ folder (as `carbody freecad-workbench` links it)
    venv = tmp_path / "cad-env"
    shipped = venv / "lib" / "python3.11" / "site-packages" / "carbody" / "shipped" / "workbench"
    shutil.copytree(WORKBENCH, shipped, ignore=shutil.ignore_patterns("__pycache__"))
    (venv / "pyvenv.cfg").write_text("home = /usr/bin\n")
    (venv / "bin").mkdir()
    (venv / "bin" / "carbody").write_text("#!/bin/sh\n")
    (venv / "bin" / "carbody").chmod(0o755)
    installed_mod = tmp_path / "Mod2"
    installed_mod.mkdir()
    (installed_mod / "carbody").symlink_to(shipped)
    result = run_freecad(f"""
import json, os, sys, FreeCAD
sys.path.insert(0, {str(mod / "carbody")!r})
from carbody_wb import core
os.environ.pop("CARBODY_COMMAND", None)
core.set_carbody_command("")
out = {{"venv": core.carbody_command(path={str(on_path)!r}),
        "path": core.carbody_command({str(mod)!r}, path={str(on_path)!r}),
        "none": core.carbody_command({str(mod)!r}, path="/nonexistent"),
        "installed": core.carbody_command({str(installed_mod / "carbody")!r}, path={str(on_path)!r}),
        "no_venv_above_root": core.venv_carbody("/")}}
try:
    core.set_carbody_command("/opt/set/carbody")
    out["preference"] = core.carbody_command(path={str(on_path)!r})
    os.environ["CARBODY_COMMAND"] = "/opt/other/carbody --flag"
    out["env"] = core.carbody_command(path={str(on_path)!r})
finally:
    core.set_carbody_command("")
print("RESULT " + json.dumps(out))
""", tmp_path, env={"CARBODY_COMMAND": ""})
    assert result["env"] == ["/opt/other/carbody", "--flag"]
    assert result["installed"] == [str(venv / "bin" / "carbody")]
    assert result["preference"] == ["/opt/set/carbody"]
    assert result["venv"] == [str(fake)]
    assert result["path"] == [str(on_path / "carbody")]
    assert result["none"] == ["carbody"] and result["no_venv_above_root"] is None


def test_freecad_workbench_links_the_shipped_workbench_into_freecads_mod_folder(tmp_path):
    """`carbody freecad-workbench`: the link in the Mod/ folder FreeCAD itself reads (asked of
    freecadcmd, here under a fresh HOME) points at the workbench carbody ships; run again it
    replaces its link; a folder of the user's own there is left alone, refused in one line."""
    from carbody.shipped import WORKBENCH as SHIPPED

    home = tmp_path / "home"
    env = {**os.environ, "HOME": str(home)}
    run = lambda *args: subprocess.run([sys.executable, "-m", "carbody", "freecad-workbench", *args],
                                       capture_output=True, text=True, env=env, cwd=REPO)
    first, again = run(), run()
    links = list(home.rglob("Mod/carbody"))
    assert first.returncode == again.returncode == 0, first.stderr
    assert len(links) == 1 and links[0].is_symlink() and links[0].resolve() == SHIPPED.resolve()
    assert (links[0] / "InitGui.py").is_file() and "restart FreeCAD" in first.stdout
    own = tmp_path / "Mod" / "carbody"
    own.mkdir(parents=True)
    refused = run("--mod-dir", str(tmp_path / "Mod"))
    lines = refused.stderr.strip().splitlines()
    assert refused.returncode == 2 and len(lines) == 1 and "not a link" in lines[0] and own.is_dir()
