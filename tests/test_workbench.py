"""The FreeCAD workbench and macro, run headless in FreeCAD 0.20's freecadcmd (a real FreeCAD)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

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


def test_the_photo_becomes_an_image_plane_with_its_aspect(tmp_path):
    import cv2
    import numpy as np

    for name in ("car.png", "car.jpg"):
        cv2.imwrite(str(tmp_path / name), np.full((300, 800, 3), 200, np.uint8))
    result = run_freecad(f"""
import json, FreeCAD
from carbody_wb import core
doc = FreeCAD.newDocument("t")
planes = [core.add_photo(doc, {str(tmp_path)!r} + "/" + n, 4000.0) for n in ("car.png", "car.jpg")]
print("RESULT " + json.dumps([[float(p.XSize), float(p.YSize)] for p in planes]))
""", tmp_path)
    assert result == [[4000.0, 1500.0], [4000.0, 1500.0]]


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
    "regions": sorted(objs),
    "valid": all(o.Shape.isValid() for o in objs.values()) and shell.Shape.isValid(),
    "faces": sum(len(o.Shape.Faces) for o in objs.values()),
    "shell_faces": len(shell.Shape.Faces),
}}))
""", tmp_path)
    assert result["regions"] == sorted(r.name for r in topology.regions)
    assert result["valid"]
    assert result["faces"] == result["shell_faces"] == len(listing["faces"])


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
    result = run_freecad(f"""
import json, FreeCAD
doc = FreeCAD.openDocument({str(saved)!r})
wire, body = doc.getObject("Wireframe"), doc.getObject("Body")
regions = [o for o in body.Group if o.Label != "BodyShell"]
print("RESULT " + json.dumps({{
    "photo": doc.getObject("Photo") is not None,
    "curve_labels": sorted(o.Label for o in wire.Group),
    "edges": sum(len(o.Shape.Edges) for o in wire.Group),
    "faces": sum(len(o.Shape.Faces) for o in regions),
    "valid": all(o.Shape.isValid() for o in wire.Group + body.Group),
}}))
""", tmp_path)
    assert result["photo"] and result["valid"]
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
