"""STEP out and in for a surfaced body: one shell, faces named and coloured by region (AP214, mm).

Writing goes through XCAF: the shell is the product (named after the car), every face a named
sub-shape with a surface colour (sRGB). Reading gives the shell back with each face's name and
colour.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from carbody.errors import SurfaceError


@dataclass
class StepBody:
    """A body read back from STEP: product name, the shell, [(face name, (r, g, b) 0..1 sRGB, face)]."""

    product: str
    shape: Any
    faces: list[tuple[str, tuple[float, float, float] | None, Any]]


def write_body_step(path: str | Path, shell, faces: list[tuple[str, tuple[float, float, float], Any]],
                    product_name: str) -> Path:
    """Write a shell with named, coloured faces as AP214 STEP in millimetres (atomically).

    Args:
        shell: the TopoDS_Shell.
        faces: (face name, sRGB colour 0..1, TopoDS_Face of ``shell``).
        product_name: STEP product name (the car).
    """
    from OCP.Quantity import Quantity_Color, Quantity_TypeOfColor
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_ColorType, XCAFDoc_DocumentTool

    from carbody.occ.step_curves import _init_step_statics, write_step_document

    _init_step_statics()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    label = shape_tool.AddShape(shell, False)
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(product_name))
    for name, rgb, face in faces:
        sub = shape_tool.AddSubShape(label, face)
        if sub.IsNull():
            raise AssertionError(f"face {name} is not a face of the shell")
        TDataStd_Name.Set_s(sub, TCollection_ExtendedString(name))
        colour = Quantity_Color(*map(float, rgb), Quantity_TypeOfColor.Quantity_TOC_sRGB)
        colour_tool.SetColor(sub, colour, XCAFDoc_ColorType.XCAFDoc_ColorSurf)

    return write_step_document(path, doc, SurfaceError)


def read_body_step(path: str | Path) -> StepBody:
    """Read a body STEP written by :func:`write_body_step` (or saved back by a CAD system), or
    the body part of an assembly (``car.step``).

    Raises:
        SurfaceError: missing, not a regular file, too large or unreadable file.
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Quantity import Quantity_Color
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDF import TDF_Label, TDF_LabelSequence
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopAbs import TopAbs_FACE
    from OCP.XCAFDoc import XCAFDoc_ColorTool, XCAFDoc_ColorType, XCAFDoc_DocumentTool

    from carbody.inputs import MAX_STEP_BYTES, input_file
    from carbody.occ.step_curves import _init_step_statics

    path = input_file(path, "STEP file", SurfaceError, MAX_STEP_BYTES)
    _init_step_statics()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.SetColorMode(True)
    try:
        ok = reader.ReadFile(str(path)) == IFSelect_RetDone and reader.Transfer(doc)
    except Exception:
        ok = False
    if not ok:
        raise SurfaceError(f"{path}: not a readable STEP file")
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    shape_tool.GetFreeShapes(roots)
    if roots.Length() == 0:
        raise SurfaceError(f"{path}: holds no shape")
    root = roots.Value(1)

    def name_of(label) -> str:
        attr = TDataStd_Name()
        return attr.Get().ToExtString() if label.FindAttribute(TDataStd_Name.GetID_s(), attr) else ""

    product = name_of(root)

    def parts(label) -> list:  # the simple shapes of an assembly (car.step), or the shape itself
        if not shape_tool.IsAssembly_s(label):
            return [label]
        components, found = TDF_LabelSequence(), []
        shape_tool.GetComponents_s(label, components)
        for i in range(1, components.Length() + 1):
            referred = TDF_Label()
            if shape_tool.GetReferredShape_s(components.Value(i), referred):
                found += parts(referred)
        return found

    shape, faces = shape_tool.GetShape_s(root), []
    for part in parts(root):
        subs = TDF_LabelSequence()
        shape_tool.GetSubShapes_s(part, subs)
        found = []
        for i in range(1, subs.Length() + 1):
            lab = subs.Value(i)
            face = shape_tool.GetShape_s(lab)
            if face.ShapeType() != TopAbs_FACE:
                continue
            colour = Quantity_Color()
            rgb = None
            if XCAFDoc_ColorTool.GetColor_s(lab, XCAFDoc_ColorType.XCAFDoc_ColorSurf, colour):
                to_srgb = Quantity_Color.Convert_LinearRGB_To_sRGB_s
                rgb = (to_srgb(colour.Red()), to_srgb(colour.Green()), to_srgb(colour.Blue()))
            found.append((name_of(lab), rgb, face))
        if found and not faces:  # the body: the part whose faces are named
            shape = shape_tool.GetShape_s(part)
        faces += found
    return StepBody(product, shape, faces)
