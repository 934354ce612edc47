"""A wireframe goes out to CAD and comes back: whoever wrote the STEP file (carbody, build123d,
CadQuery, FreeCAD — tests/test_workbench.py), its named curves read back and surface; and the
names carbody writes are the ones other readers show (gmsh, OCCT's XCAF; FreeCAD in
tests/test_workbench.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from carbody.errors import TemplateError
from carbody.wireframe import as_wireframe, read_wireframe, write_wireframe
from tests.conftest import run_cli


@pytest.fixture(scope="module")
def car(templates):
    return templates[0][1]


def bezier_edges(wf, both_halves=True):
    import build123d as bd

    edges = []
    for name, poles in wf.named_curves(both_halves):
        edge = bd.Edge.make_bezier(*[tuple(map(float, p)) for p in poles])
        edge.label = name
        edges.append(edge)
    return edges


def xcaf_parts(path):
    """[(part name, number of edges)] under the root of a STEP file, as OCCT's XCAF reads it."""
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDF import TDF_LabelSequence
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_DocumentTool, XCAFDoc_ShapeTool

    from carbody.occ.shapes import sub_shapes
    from carbody.occ.step_curves import _label_name

    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.ReadFile(str(path))
    reader.Transfer(doc)
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    tool.GetFreeShapes(roots)
    comps = TDF_LabelSequence()
    XCAFDoc_ShapeTool.GetComponents_s(roots.Value(1), comps, False)
    out = []
    for k in range(1, comps.Length() + 1):
        from OCP.TDF import TDF_Label

        ref = TDF_Label()
        XCAFDoc_ShapeTool.GetReferredShape_s(comps.Value(k), ref)
        out.append((_label_name(ref), len(sub_shapes(XCAFDoc_ShapeTool.GetShape_s(ref), "edge"))))
    return _label_name(roots.Value(1)), out


def test_carbody_writes_one_named_part_per_curve_and_reads_it_back(car, tmp_path, topology):
    path = write_wireframe(tmp_path / "car.step", car, both_halves=True)
    product, parts = xcaf_parts(path)
    names = [n for n, _ in car.named_curves(both_halves=True)]
    assert product == car.name and [n for n, _ in parts] == names and all(k == 1 for _, k in parts)
    text = path.read_text()
    assert "EDGE_BASED_WIREFRAME_SHAPE_REPRESENTATION" in text and "SI_UNIT(.MILLI.,.METRE.)" in text
    back = read_wireframe(path)
    assert back.name == car.name and np.abs(back.control_points - car.control_points).max() < 1e-9


def test_gmsh_shows_every_curve_by_name(car, tmp_path):
    try:
        import gmsh
    except (ImportError, OSError) as exc:  # the wheel, or the system libraries it loads
        pytest.skip(f"gmsh cannot be imported: {exc}")
    path = write_wireframe(tmp_path / "car.step", car, both_halves=True)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        names = [gmsh.model.getEntityName(1, tag) for _, tag in gmsh.model.getEntities(1)]
    finally:
        gmsh.finalize()
    expected = {f"Shapes/{car.name}/{n}/{n}" for n, _ in car.named_curves(both_halves=True)}
    assert set(names) == expected and len(names) == len(expected)


def test_a_build123d_compound_of_labelled_edges_reads_back_as_written(car, tmp_path, templates, template_copy):
    """... and as a template: a car saved by build123d in place of a template's file loads."""
    import build123d as bd

    from carbody.templates import load_template

    compound = bd.Compound(children=bezier_edges(car))
    compound.label = car.name
    bd.export_step(compound, str(tmp_path / "b3d.step"))
    row = templates[0][0]
    bd.export_step(compound, str(template_copy / row["file"]))
    for wire in (read_wireframe(tmp_path / "b3d.step"), as_wireframe(compound),
                 load_template(row["name"], template_copy)):
        assert wire.name == car.name and np.abs(wire.control_points - car.control_points).max() < 1e-9


def test_a_cadquery_assembly_of_named_edges_reads_back_as_written(car, tmp_path):
    import cadquery as cq

    assy = cq.Assembly(name="cq car")
    for edge in bezier_edges(car, both_halves=False):
        # a curve placed by its assembly location still lands where it was
        assy.add(cq.Edge(edge.wrapped).translate((0, -100, 0)), name=edge.label, loc=cq.Location((0, 100, 0)))
    assy.export(str(tmp_path / "cq.step"), "STEP")
    for wire in (read_wireframe(tmp_path / "cq.step"), as_wireframe(assy)):
        assert wire.name == "cq car" and np.abs(wire.control_points - car.control_points).max() < 1e-6


def test_curves_written_without_names_are_refused_in_one_line(car, tmp_path):
    import cadquery as cq

    compound = cq.Compound.makeCompound([cq.Edge(e.wrapped) for e in bezier_edges(car)])
    cq.exporters.export(compound, str(tmp_path / "plain.step"))
    with pytest.raises(TemplateError, match="holds a curve with no name") as err:
        read_wireframe(tmp_path / "plain.step")
    assert "\n" not in str(err.value)
    with pytest.raises(TemplateError, match="carries no curve names"):
        as_wireframe(compound)


def test_earlier_files_with_named_curve_sets_still_read(car, tmp_path):
    """carbody's files before this one: a single product, a named GEOMETRIC_CURVE_SET per curve."""
    from OCP.BRep import BRep_Builder
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopoDS import TopoDS_Compound
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    from carbody.occ.step_curves import _init_step_statics, bezier_edge

    _init_step_statics()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    builder, compound = BRep_Builder(), TopoDS_Compound()
    builder.MakeCompound(compound)
    edges = [bezier_edge(p) for _, p in car.named_curves()]
    for e in edges:
        builder.Add(compound, e)
    label = tool.AddShape(compound, False)
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(car.name))
    for (name, _), e in zip(car.named_curves(), edges):
        TDataStd_Name.Set_s(tool.AddSubShape(label, e), TCollection_ExtendedString(name))
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.Transfer(doc, STEPControl_AsIs)
    writer.Write(str(tmp_path / "old.step"))
    assert "GEOMETRIC_CURVE_SET('front_centre'" in (tmp_path / "old.step").read_text()
    back = read_wireframe(tmp_path / "old.step")
    assert back.name == car.name and np.abs(back.control_points - car.control_points).max() < 1e-9


def test_wireframe_json_round_trip_and_the_cli_converts_and_surfaces_it(car, tmp_path):
    from carbody.wireframe import wireframe_json, write_wireframe_json

    data = wireframe_json(car, both_halves=True)
    right = {c["name"]: c for c in data["curves"]}["roof_side_1_right"]
    assert right["start"] == "roof_front_corner_right" and right["poles"][0][0] < 0
    assert {c["name"]: c for c in data["curves"]}["windshield_top_right"]["start"] == "roof_front_centre"
    path = write_wireframe_json(tmp_path / "car.json", car, both_halves=True)
    assert np.abs(read_wireframe(path).control_points - car.control_points).max() == 0
    step = tmp_path / "car.step"
    run_cli("wireframe", str(path), "-o", str(step), check=True)
    assert np.abs(read_wireframe(step).control_points - car.control_points).max() < 1e-9
    run_cli("surface", str(path), "-o", str(tmp_path / "body.step"), "--report", str(tmp_path / "r.json"), check=True)
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["folds"] == [] and report["shell"]["valid"]
    assert len(report["faces"]) == report["shell"]["faces"]
    assert {f["region"] for f in report["faces"]} == set(report["regions"])


def test_a_bad_wireframe_json_is_one_line(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "carbody-wireframe", "curves": [{"name": "x", "poles": [1, 2]}]}))
    with pytest.raises(TemplateError, match="not a carbody wireframe JSON file"):
        read_wireframe(bad)
