"""The FreeCAD workbench and macro, run headless in FreeCAD 0.20's freecadcmd (a real FreeCAD)."""
from __future__ import annotations

import json
import os
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
    timer ticks all along), each stage line comes as the command writes it, and a failure ends
    in its one line."""
    fake = tmp_path / "fake_carbody.py"
    fake.write_text("import sys, time\n"
                    "if sys.argv[1] == 'parts':\n"
                    "    print('{\"file\": \"' + sys.argv[2].rsplit('/', 1)[-1] + '\"}'); sys.exit(0)\n"
                    "if sys.argv[1] == 'fail':\n"
                    "    print('carbody reconstruct: error: the keypoints are coincident', file=sys.stderr); sys.exit(2)\n"
                    "for stage in ('view', 'fit', 'surfaces', 'write'):\n"
                    "    print(f'carbody: stage {stage}', file=sys.stderr, flush=True); time.sleep(0.3)\n"
                    "print('{\"ok\": true}')\n")
    result = run_freecad(f"""
import json, sys, time, FreeCAD
from PySide import QtCore
from carbody_wb import core
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
# the whole job: reconstruct, then the two STEP files' parts listings, one after the other
loop = QtCore.QEventLoop()
said, finished = [], {{}}
def job_done(ok, result):
    finished.update(ok=ok, result=result); loop.quit()
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
    assert result["job"] == {"ok": True, "result": {"wireframe": {"file": "wireframe.step"}, "body": {"file": "body.step"}}}
    assert result["said"] == ["stage view", "stage fit", "stage surfaces", "stage write",
                              "reading the wireframe back", "reading the body back"]


def test_the_carbody_command_is_found_on_path_or_in_the_workbenchs_venv(tmp_path):
    """With no $CARBODY_COMMAND and nothing set: ``carbody`` on PATH, else the venv beside (or
    above) the workbench's real folder, a link into FreeCAD's Mod/ followed."""
    repo = tmp_path / "repo"
    (repo / ".venv" / "bin").mkdir(parents=True)
    script = repo / ".venv" / "bin" / "carbody"
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    (repo / "workbench").mkdir()
    (tmp_path / "Mod").mkdir()
    (tmp_path / "Mod" / "carbody").symlink_to(repo / "workbench")
    on_path = tmp_path / "bin"
    on_path.mkdir()
    (on_path / "carbody").write_text("#!/bin/sh\n")
    (on_path / "carbody").chmod(0o755)
    result = run_freecad(f"""
import json, FreeCAD
from carbody_wb import core
linked = {str(tmp_path / "Mod" / "carbody")!r}
print("RESULT " + json.dumps({{
    "venv": core.carbody_command(linked, path="/nonexistent"),
    "path": core.carbody_command(linked, path={str(on_path)!r}),
    "none": core.carbody_command({str(tmp_path / "Mod")!r}, path="/nonexistent"),
}}))
""", tmp_path, env={"CARBODY_COMMAND": ""})
    assert result["venv"] == [str(script)]
    assert result["path"] == [str(on_path / "carbody")]
    assert result["none"] == ["carbody"]


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
