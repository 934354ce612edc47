"""The body STEP reads as valid in two independent readers: FreeCAD 0.20 and arris (Rust)."""
from __future__ import annotations

import json
import shutil
import subprocess

import pytest

from carbody.templates import load_manifest, load_template


@pytest.fixture(scope="module")
def body_step(tmp_path_factory):
    from carbody.surface import build_body
    from carbody.surface.body import face_names, write_body

    body = build_body(load_template(load_manifest()[0]["name"]))
    path = write_body(tmp_path_factory.mktemp("body") / "body.step", body)
    return path, body, face_names(body)


FREECAD_SCRIPT = """
import json
import Part
shape = Part.read({path!r})
out = {{"valid": shape.isValid(), "type": shape.ShapeType, "faces": len(shape.Faces),
        "shells": len(shape.Shells),
        "free_edges": len([e for e in shape.Edges if len(shape.ancestorsOfType(e, Part.Face)) == 1]),
        "bbox": [shape.BoundBox.XMin, shape.BoundBox.YMin, shape.BoundBox.ZMin,
                 shape.BoundBox.XMax, shape.BoundBox.YMax, shape.BoundBox.ZMax]}}
with open({out!r}, "w") as f:
    f.write(json.dumps(out))
"""


@pytest.mark.freecad
@pytest.mark.skipif(shutil.which("freecadcmd") is None, reason="needs freecadcmd (FreeCAD 0.20)")
def test_freecad_reads_a_valid_shell(body_step, tmp_path):
    path, body, _ = body_step
    script, out = tmp_path / "check.py", tmp_path / "out.json"
    script.write_text(FREECAD_SCRIPT.format(path=str(path), out=str(out)))
    proc = subprocess.run(["freecadcmd", str(script)], capture_output=True, text=True, timeout=300)
    assert out.exists(), proc.stdout[-2000:] + proc.stderr[-2000:]
    res = json.loads(out.read_text())
    assert res["valid"] is True
    assert res["type"] == "Shell" and res["shells"] == 1
    assert res["faces"] == len(body.faces)
    assert res["free_edges"] == body.report["shell"]["free_edges"]
    assert res["bbox"][0] == pytest.approx(-res["bbox"][3], abs=1e-3)  # both halves


def test_arris_reads_one_checked_sheet_with_colours(body_step):
    arris = pytest.importorskip("arris")

    path, body, names = body_step
    model = arris.Model()
    read = model.read_step(path.read_text())
    assert len(read.solids) == 1
    solid = read.solids[0]
    assert solid.ok and solid.refusal is None
    assert model.body_kind(solid.body) == "sheet"  # an open shell, not a solid
    assert len(model.shells(solid.body)) == 1
    assert len(model.faces(solid.body)) == len(body.faces)
    report = model.check(solid.body)
    assert report.ok, report.violations
    assert [p.name for p in read.products] == [body.name]
    assert len(read.face_colours) == len(body.faces)
