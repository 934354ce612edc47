"""STEP out for the whole car: named parts of one AP214 assembly, their sub-shapes named and
coloured (``car.step``: the wireframe and the body).

The XCAF document is the one ``cadquery.Assembly`` export makes of the same parts (a root
assembly named after the car; each part a compound of its shape under the part's name, with a
surface colour, referenced by a component of the same name; sub-shape names, and sub-shape
colours as generic colours), built here with OCCT's XCAF tools directly: importing CadQuery
for it cost a fresh ``carbody reconstruct`` about 1.5 s (it imports all of VTK).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from carbody.errors import CarbodyError

#: sRGB colour, 0..1.
Colour = tuple[float, float, float]


@dataclass
class AssemblyPart:
    """One part of an assembly.

    Attributes:
        name: the part's name (and its component's).
        shape: its TopoDS shape (a compound of edges, a shell, ...).
        colour: its surface colour, sRGB 0..1.
        sub_shapes: [(name, TopoDS sub-shape of ``shape``, sRGB colour or None)].
    """

    name: str
    shape: Any
    colour: Colour
    sub_shapes: list[tuple[str, Any, Colour | None]] = field(default_factory=list)


def write_assembly_step(path: str | Path, product_name: str, parts: list[AssemblyPart],
                        error: type[CarbodyError]) -> Path:
    """Write ``parts`` as one AP214 assembly named ``product_name`` in millimetres (atomically).

    Raises:
        error: OCCT cannot translate the document.
        OSError: the file cannot be written.
        AssertionError: a sub-shape is not a sub-shape of its part.
    """
    from OCP.BinXCAFDrivers import BinXCAFDrivers
    from OCP.BRep import BRep_Builder
    from OCP.Quantity import Quantity_Color, Quantity_ColorRGBA, Quantity_TypeOfColor
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS_Compound
    from OCP.XCAFApp import XCAFApp_Application
    from OCP.XCAFDoc import XCAFDoc_ColorType, XCAFDoc_DocumentTool, XCAFDoc_ShapeTool

    from carbody.occ.step_curves import _init_step_statics, write_step_document

    def named(label, name: str):
        TDataStd_Name.Set_s(label, TCollection_ExtendedString(name))
        return label

    def rgba(colour: Colour):
        return Quantity_ColorRGBA(Quantity_Color(*map(float, colour), Quantity_TypeOfColor.Quantity_TOC_sRGB), 1)

    _init_step_statics()
    app = XCAFApp_Application.GetApplication_s()
    BinXCAFDrivers.DefineFormat_s(app)
    doc = TDocStd_Document(TCollection_ExtendedString("BinXCAF"))
    app.InitDocument(doc)
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colour_tool = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    auto_naming = XCAFDoc_ShapeTool.AutoNaming_s()
    XCAFDoc_ShapeTool.SetAutoNaming_s(False)  # every label gets our name, none OCCT's
    try:
        root = named(shape_tool.NewShape(), product_name)
        builder = BRep_Builder()
        for part in parts:
            compound = TopoDS_Compound()
            builder.MakeCompound(compound)
            builder.Add(compound, part.shape)
            label = shape_tool.NewShape()
            shape_tool.SetShape(label, compound)
            named(label, part.name)
            colour_tool.SetColor(label, rgba(part.colour), XCAFDoc_ColorType.XCAFDoc_ColorSurf)
            for name, sub_shape, colour in part.sub_shapes:
                sub = shape_tool.AddSubShape(label, sub_shape)
                if sub.IsNull():
                    raise AssertionError(f"{name} is not a sub-shape of the part {part.name}")
                named(sub, name)
                if colour is not None:
                    colour_tool.SetColor(sub, rgba(colour), XCAFDoc_ColorType.XCAFDoc_ColorGen)
            named(shape_tool.AddComponent(root, label, TopLoc_Location()), part.name)
        shape_tool.UpdateAssemblies()
    finally:
        XCAFDoc_ShapeTool.SetAutoNaming_s(auto_naming)
    return write_step_document(path, doc, error)
