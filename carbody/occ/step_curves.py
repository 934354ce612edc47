"""STEP in and out for named curves (the wireframe), through OCCT.

Each curve is written as its own part of an assembly named after the car: the part is named
after the curve and holds one edge on a B-spline (a cubic Bezier is a one-span B-spline), in
millimetres, AP214 -- the structure FreeCAD, gmsh and OCCT's XCAF show names for. Reading finds
curves by name on single-curve parts (FreeCAD's export, CadQuery assemblies, build123d compounds)
and on any named STEP representation item (curve set, edge, curve), so a file saved back by
another CAD system that keeps the names reads as well.
"""
from __future__ import annotations

import io
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from carbody.errors import CarbodyError, TemplateError
from carbody.signals import held
from carbody.tolerances import MAX_COORDINATE_MM, STEP_ROUND_MM


@dataclass
class NamedCurve:
    """A polynomial B-spline curve (Bezier when it has one span) read from or written to STEP.

    ``poles`` is (n, 3) float, mm; ``degree`` its degree; ``spans`` its number of knot spans.
    """

    name: str
    poles: np.ndarray
    degree: int = 3
    spans: int = 1
    rational: bool = False


def _init_step_statics() -> None:
    # Init_s must come first or the statics below are silently dropped.
    from OCP.Interface import Interface_Static
    from OCP.STEPCAFControl import STEPCAFControl_Controller

    from carbody.occ import quiet_occt

    quiet_occt()
    STEPCAFControl_Controller.Init_s()
    Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    Interface_Static.SetCVal_s("xstep.cascade.unit", "MM")
    Interface_Static.SetIVal_s("write.stepcaf.subshapes.name", 1)
    Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1)


def bezier_edge(poles: np.ndarray):
    """A TopoDS_Edge on a Geom_BezierCurve through (n, 3) poles in mm."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.Geom import Geom_BezierCurve
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array1OfPnt

    arr = TColgp_Array1OfPnt(1, len(poles))
    for i, p in enumerate(poles):
        arr.SetValue(i + 1, gp_Pnt(*map(float, p)))
    return BRepBuilderAPI_MakeEdge(Geom_BezierCurve(arr)).Edge()


def atomic_write(path: str | Path, write) -> Path:
    """Call ``write(tmp_path)`` then move the result onto ``path``: never a half-written file."""
    path = Path(path)
    if not path.parent.is_dir():
        raise TemplateError(f"{path}: folder {path.parent} does not exist")
    tmp = None
    try:
        with held():  # made and noted whole, so that it is removed
            fd, tmp = tempfile.mkstemp(suffix=path.suffix, dir=path.parent, prefix=f".{path.stem}.")
            os.close(fd)
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual mode
        os.replace(tmp, path)
    except OSError as exc:  # (a full disk): said of the file asked for, not of the temporary one
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_step_document(path: str | Path, doc, error: type[CarbodyError]) -> Path:
    """Write an XCAF document (names and colours on) as AP214 STEP in millimetres, atomically.

    OCCT writes into memory and Python writes the file, so that a full disk or a refused write
    is the file system's own error (``OSError``, "no space left on device"), not OCCT's bare
    "could not write".

    Raises:
        error: OCCT cannot translate the document.
        OSError: the file cannot be written.
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Writer
    from OCP.STEPControl import STEPControl_AsIs

    _init_step_statics()
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.SetColorMode(True)
    writer.SetLayerMode(True)
    stream = io.BytesIO()
    if not writer.Transfer(doc, STEPControl_AsIs) or writer.WriteStream(stream) != IFSelect_RetDone:
        raise error(f"{path}: OCCT could not write the STEP file")
    data = stream.getvalue()
    return atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def write_curves_step(path: str | Path, curves: list[NamedCurve] | list[tuple[str, np.ndarray]],
                      product_name: str) -> Path:
    """Write named polynomial curves to an AP214 STEP file in millimetres.

    The file is an assembly: the product named ``product_name`` (the car) holds one part per
    curve, the part named after the curve, its shape an edge-based wireframe of that one edge
    (``EDGE_BASED_WIREFRAME_SHAPE_REPRESENTATION``; the edge carries the name too). That is the
    structure other readers show names for: FreeCAD makes one object per part with the curve's
    name, gmsh names each curve entity ``Shapes/<car>/<curve>/<curve>``, and OCCT's XCAF gives
    each part its label. (A named ``GEOMETRIC_CURVE_SET`` inside one product, as carbody wrote
    before, is shown by none of them; :func:`read_curves_step` still reads it.)

    Args:
        path: output file (written atomically).
        curves: (name, poles) pairs or :class:`NamedCurve`; poles (n, 3) float, mm, of a Bezier
            curve of degree n - 1. Poles are rounded to
            :data:`~carbody.tolerances.STEP_ROUND_MM` so they survive the text format.
        product_name: the STEP product name (the car).
    Returns:
        the written path.
    """
    items = [c if isinstance(c, NamedCurve) else NamedCurve(c[0], np.asarray(c[1], float)) for c in curves]
    text = _wireframe_assembly_text(product_name, [(c.name, np.asarray(c.poles, float)) for c in items],
                                    Path(path).name)

    def write(tmp: str) -> None:
        Path(tmp).write_text(text, encoding="ascii")

    return atomic_write(path, write)


def _step_string(text: str) -> str:
    """A STEP string literal: quotes doubled, anything past ASCII as ``\\X2\\...\\X0\\``."""
    out, wide = [], []

    def flush():
        if wide:
            out.append("\\X2\\" + "".join(f"{ord(ch):04X}" for ch in wide) + "\\X0\\")
            wide.clear()

    for ch in text:
        if 32 <= ord(ch) < 127:
            flush()
            out.append("''" if ch == "'" else "\\\\" if ch == "\\" else ch)
        else:
            wide.append(ch)
    flush()
    return "'" + "".join(out) + "'"


def _step_real(value: float) -> str:
    """A STEP REAL (always with a decimal point: ``0.``, ``1.E-07``)."""
    s = repr(float(value)).upper()
    mantissa, _, exponent = s.partition("E")
    if "." not in mantissa:
        mantissa += "."
    return mantissa + ("E" + exponent if exponent else "")


def _wireframe_assembly_text(product_name: str, curves: list[tuple[str, np.ndarray]], file_name: str) -> str:
    """The Part 21 text of :func:`write_curves_step` (entities numbered in writing order)."""
    import time

    from carbody import __version__

    lines: list[str] = []

    def add(entity: str) -> int:
        lines.append(entity)
        return len(lines)

    def ref(i: int) -> str:
        return f"#{i}"

    def refs(ids) -> str:
        return "(" + ",".join(ref(i) for i in ids) + ")"

    def point(p) -> int:
        return add(f"CARTESIAN_POINT('',({','.join(_step_real(v) for v in p)}))")

    app = add("APPLICATION_CONTEXT('core data for automotive mechanical design processes')")
    add(f"APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,{ref(app)})")
    product_context = add(f"PRODUCT_CONTEXT('',{ref(app)},'mechanical')")
    definition_context = add(f"PRODUCT_DEFINITION_CONTEXT('part definition',{ref(app)},'design')")
    mm = add("( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")
    rad = add("( NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.) )")
    sr = add("( NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT() )")
    accuracy = add(f"UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),{ref(mm)},"
                   "'distance_accuracy_value','confusion accuracy')")
    context = add(f"( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT(({ref(accuracy)})) "
                  f"GLOBAL_UNIT_ASSIGNED_CONTEXT({refs((mm, rad, sr))}) "
                  "REPRESENTATION_CONTEXT('Context #1','3D Context with UNIT and UNCERTAINTY') )")
    origin = point((0.0, 0.0, 0.0))
    z_axis = add("DIRECTION('',(0.,0.,1.))")
    x_axis = add("DIRECTION('',(1.,0.,0.))")

    def axis() -> int:
        return add(f"AXIS2_PLACEMENT_3D('',{ref(origin)},{ref(z_axis)},{ref(x_axis)})")

    def product(name: str) -> tuple[int, int]:
        """(product, product definition shape) of a part named ``name``."""
        literal = _step_string(name)
        prod = add(f"PRODUCT({literal},{literal},'',({ref(product_context)}))")
        add(f"PRODUCT_RELATED_PRODUCT_CATEGORY('part',$,({ref(prod)}))")
        formation = add(f"PRODUCT_DEFINITION_FORMATION('','',{ref(prod)})")
        definition = add(f"PRODUCT_DEFINITION('design','',{ref(formation)},{ref(definition_context)})")
        return definition, add(f"PRODUCT_DEFINITION_SHAPE('','',{ref(definition)})")

    # the car: an assembly whose representation holds one placement per part
    car_definition, car_shape = product(product_name)
    car_axis = axis()
    part_axes = [axis() for _ in curves]
    car_rep = add(f"SHAPE_REPRESENTATION('',{refs([car_axis, *part_axes])},{ref(context)})")
    add(f"SHAPE_DEFINITION_REPRESENTATION({ref(car_shape)},{ref(car_rep)})")
    for k, ((name, poles), placed) in enumerate(zip(curves, part_axes), start=1):
        literal = _step_string(name)
        definition, shape = product(name)
        poles = np.round(np.asarray(poles, float) / STEP_ROUND_MM) * STEP_ROUND_MM
        pole_ids = [point(p) for p in poles]
        n = len(poles)
        curve = add(f"B_SPLINE_CURVE_WITH_KNOTS('',{n - 1},{refs(pole_ids)},.UNSPECIFIED.,.F.,.F.,"
                    f"({n},{n}),(0.,1.),.PIECEWISE_BEZIER_KNOTS.)")
        v0 = add(f"VERTEX_POINT('',{ref(point(poles[0]))})")
        v1 = add(f"VERTEX_POINT('',{ref(point(poles[-1]))})")
        edge = add(f"EDGE_CURVE({literal},{ref(v0)},{ref(v1)},{ref(curve)},.T.)")
        edge_set = add(f"CONNECTED_EDGE_SET('',({ref(edge)}))")
        model = add(f"EDGE_BASED_WIREFRAME_MODEL('',({ref(edge_set)}))")
        part_axis = axis()
        rep = add(f"EDGE_BASED_WIREFRAME_SHAPE_REPRESENTATION({literal},{refs((part_axis, model))},{ref(context)})")
        add(f"SHAPE_DEFINITION_REPRESENTATION({ref(shape)},{ref(rep)})")
        usage = add(f"NEXT_ASSEMBLY_USAGE_OCCURRENCE('{k}',{literal},'',{ref(car_definition)},{ref(definition)},$)")
        transform = add(f"ITEM_DEFINED_TRANSFORMATION('','',{ref(part_axis)},{ref(placed)})")
        relation = add(f"( REPRESENTATION_RELATIONSHIP('','',{ref(rep)},{ref(car_rep)}) "
                       f"REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION({ref(transform)}) "
                       "SHAPE_REPRESENTATION_RELATIONSHIP() )")
        placement = add(f"PRODUCT_DEFINITION_SHAPE('Placement','Placement of an item',{ref(usage)})")
        add(f"CONTEXT_DEPENDENT_SHAPE_REPRESENTATION({ref(relation)},{ref(placement)})")
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime())
    header = ["ISO-10303-21;", "HEADER;",
              "FILE_DESCRIPTION(('carbody wireframe: one part per named curve'),'2;1');",
              f"FILE_NAME({_step_string(file_name)},'{stamp}',('carbody'),('carbody'),"
              f"'carbody {__version__}','carbody {__version__}','');",
              "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));", "ENDSEC;", "DATA;"]
    body = [f"#{i} = {e};" for i, e in enumerate(lines, start=1)]
    return "\n".join(header + body + ["ENDSEC;", "END-ISO-10303-21;", ""])


def _geom_curve(curve, name: str, reversed_: bool = False) -> NamedCurve:
    """A NamedCurve from any bounded Geom_Curve (Bezier, B-spline, trimmed)."""
    from OCP.GeomConvert import GeomConvert

    bspline = GeomConvert.CurveToBSplineCurve_s(curve)
    poles = np.array([[bspline.Pole(i).X(), bspline.Pole(i).Y(), bspline.Pole(i).Z()]
                      for i in range(1, bspline.NbPoles() + 1)])
    if reversed_:
        poles = poles[::-1].copy()
    return NamedCurve(name, poles, bspline.Degree(), bspline.NbKnots() - 1, bspline.IsRational())


_LENGTH_UNITS_MM = {"MM": 1.0, "M": 1000.0, "CM": 10.0, "INCH": 25.4, "IN": 25.4, "FT": 304.8, "UM": 1e-3}


def _checked(curve: NamedCurve, path: Path) -> NamedCurve:
    """``curve``, refused when a control point lies further than any car's (or is NaN)."""
    near = np.all(np.abs(curve.poles) <= MAX_COORDINATE_MM, axis=1)  # NaN is not near either
    if not near.all():
        far = curve.poles[~near][0]
        raise TemplateError(f"{path}: curve {curve.name!r} has a control point at {far.tolist()} mm, "
                            f"further than any car's ({MAX_COORDINATE_MM:g} mm from the origin)")
    return curve


def read_curves_step(path: str | Path) -> tuple[str, list[NamedCurve]]:
    """Read every curve of a STEP file with the name the file gives it.

    Names are found wherever STEP carries them: on the products of single-curve parts (what
    carbody writes, and what FreeCAD, CadQuery assemblies and build123d compounds of labelled
    edges write: a part per object, named after it), and on named curve sets, edges and curves
    inside one product (carbody's earlier files). Parts are placed as the assembly says. Curves
    are returned in millimetres whatever the file's length unit.

    Returns:
        (product name of the root, curves in file order); curves the file leaves unnamed come
        last, named "".
    Raises:
        TemplateError: the file is missing, not a regular file, too large or not a readable STEP
            file, or a control point lies further than :data:`~carbody.tolerances.MAX_COORDINATE_MM`.
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDF import TDF_LabelSequence
    from OCP.TDocStd import TDocStd_Document
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    from carbody.inputs import MAX_STEP_BYTES, input_file
    from carbody.occ.shapes import sub_shapes

    path = input_file(path, "STEP file", TemplateError, MAX_STEP_BYTES)
    _init_step_statics()
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    try:
        ok = reader.ReadFile(str(path)) == IFSelect_RetDone and reader.Transfer(doc)
    except Exception:  # OCCT raises Standard_Failure on some garbage
        ok = False
    if not ok:
        raise TemplateError(f"{path}: not a readable STEP file")
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    roots = TDF_LabelSequence()
    shape_tool.GetFreeShapes(roots)
    leaves = []  # (name, located shape) of every part, in file order
    for i in range(1, roots.Length() + 1):
        leaves += _xcaf_parts(shape_tool, roots.Value(i))
    product = _label_name(roots.Value(1)) if roots.Length() else ""
    by_part = [(name, shape) for name, shape in leaves if name and len(sub_shapes(shape, "edge")) == 1]
    curves = [edge_curve(sub_shapes(shape, "edge")[0], name, missing_ok=True) for name, shape in by_part]
    n_edges = sum(len(sub_shapes(shape, "edge")) for _, shape in leaves)
    if len(by_part) < len(leaves) or None in curves:
        # parts holding several curves (or none, or a curve collapsed to a point, which OCCT
        # reads as an edge without geometry): their names are on the curves themselves
        raw = _named_items(reader.ChangeReader().StepModel(), reader, path)
        first = {}
        for c in raw:
            first.setdefault(c.name, c)
        curves = [c if c is not None else first.get(name) for c, (name, _) in zip(curves, by_part)]
        found = {c.name for c in curves if c is not None}
        curves = [c for c in curves if c is not None] + [c for c in raw if c.name not in found]
        n_edges = max(n_edges, len(curves))
    if not product:
        product = _first_product_name(reader.ChangeReader().StepModel())
    curves = [_checked(c, path) for c in curves]
    curves += [NamedCurve("", np.zeros((0, 3)))] * max(0, n_edges - len(curves))
    return product, curves


#: What OCCT's STEP writer names a product it was given no name for.
_OCCT_DEFAULT_NAME = "Open CASCADE STEP translator"


def _label_name(label) -> str:
    """A label's name; "" for none, or for the placeholder OCCT writes for an unnamed product."""
    from OCP.TDataStd import TDataStd_Name

    attr = TDataStd_Name()
    name = attr.Get().ToExtString() if label.FindAttribute(TDataStd_Name.GetID_s(), attr) else ""
    return "" if name.startswith(_OCCT_DEFAULT_NAME) else name


def _xcaf_parts(shape_tool, label, location=None) -> list[tuple[str, object]]:
    """(name, shape placed in the file's frame) of every simple-shape part under ``label``.

    A part used once is named after its product; one used several times after each instance.
    """
    from OCP.TDF import TDF_Label, TDF_LabelSequence
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFDoc import XCAFDoc_ShapeTool

    location = location or TopLoc_Location()
    if not XCAFDoc_ShapeTool.IsAssembly_s(label):
        return [(_label_name(label), XCAFDoc_ShapeTool.GetShape_s(label).Moved(location))]
    components = TDF_LabelSequence()
    XCAFDoc_ShapeTool.GetComponents_s(label, components, False)
    uses: dict[str, int] = {}
    entries = []
    for k in range(1, components.Length() + 1):
        comp = components.Value(k)
        referred = TDF_Label()
        XCAFDoc_ShapeTool.GetReferredShape_s(comp, referred)
        entries.append((comp, referred))
        uses[_entry(referred)] = uses.get(_entry(referred), 0) + 1
    out = []
    for comp, referred in entries:
        placed = location.Multiplied(XCAFDoc_ShapeTool.GetLocation_s(comp))
        parts = _xcaf_parts(shape_tool, referred, placed)
        if len(parts) == 1 and uses[_entry(referred)] > 1 and _label_name(comp):
            parts = [(_label_name(comp), parts[0][1])]
        out += parts
    return out


def _entry(label) -> str:
    from OCP.TCollection import TCollection_AsciiString
    from OCP.TDF import TDF_Tool

    entry = TCollection_AsciiString()
    TDF_Tool.Entry_s(label, entry)
    return entry.ToCString()


def edge_curve(edge, name: str, missing_ok: bool = False) -> NamedCurve | None:
    """The NamedCurve of a TopoDS_Edge, in its own direction and over its own range; None for an
    edge without 3D geometry with ``missing_ok``."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.Geom import Geom_TrimmedCurve
    from OCP.TopAbs import TopAbs_REVERSED

    curve = BRep_Tool.Curve_s(edge, 0.0, 0.0)
    if curve is None:
        if missing_ok:
            return None
        raise TemplateError(f"curve {name!r} has no 3D geometry")
    adaptor = BRepAdaptor_Curve(edge)
    first, last = adaptor.FirstParameter(), adaptor.LastParameter()
    if abs(first - curve.FirstParameter()) > 1e-12 or abs(last - curve.LastParameter()) > 1e-12:
        curve = Geom_TrimmedCurve(curve, first, last)
    return _geom_curve(curve, name, edge.Orientation() == TopAbs_REVERSED)


def _first_product_name(model) -> str:
    from OCP.StepBasic import StepBasic_Product

    for i in range(1, model.NbEntities() + 1):
        entity = model.Value(i)
        if isinstance(entity, StepBasic_Product):
            name = entity.Name().ToCString()
            return "" if name.startswith(_OCCT_DEFAULT_NAME) else name
    return ""


def _named_items(model, reader, path: Path) -> list[NamedCurve]:
    """Curves named on a representation item (curve set, edge, curve), in file order."""
    from OCP.StepData import StepData_Factors
    from OCP.StepGeom import StepGeom_Curve
    from OCP.StepShape import StepShape_EdgeCurve, StepShape_GeometricCurveSet
    from OCP.StepToGeom import StepToGeom
    from OCP.TColStd import TColStd_SequenceOfAsciiString

    units, angles, solids = (TColStd_SequenceOfAsciiString() for _ in range(3))
    reader.ChangeReader().FileUnits(units, angles, solids)
    unit = units.Value(1).ToCString().upper() if units.Length() else "MM"
    factors = StepData_Factors()
    factors.InitializeFactors(_LENGTH_UNITS_MM.get(unit, 1.0), 1.0, 1.0)
    curves: list[NamedCurve] = []
    for i in range(1, model.NbEntities() + 1):
        entity = model.Value(i)  # OCP hands back the most derived type
        geometry: list[tuple[object, bool]] = []
        if isinstance(entity, StepShape_GeometricCurveSet):
            geometry = [(entity.ElementsValue(k).Curve(), False) for k in range(1, entity.NbElements() + 1)]
        elif isinstance(entity, StepShape_EdgeCurve):
            geometry = [(entity.EdgeGeometry(), not entity.SameSense())]
        elif isinstance(entity, StepGeom_Curve) and entity.Name().ToCString():
            geometry = [(entity, False)]
        name = entity.Name().ToCString() if geometry else ""
        if not name:
            continue
        for step_curve, reversed_ in geometry:
            if step_curve is None:
                continue
            geom = StepToGeom.MakeCurve_s(step_curve, factors)
            if geom is None:
                raise TemplateError(f"{path}: curve {name!r} has geometry OCCT cannot read")
            curves.append(_checked(_geom_curve(geom, name, reversed_), path))
    return curves


def cubic_fit_error(poles: np.ndarray, degree: int, spans: int) -> tuple[np.ndarray, float]:
    """The cubic Bezier through a polynomial B-spline's ends that best matches it, and how far off.

    Another CAD system may save a cubic Bezier with its degree raised or extra knots; this finds
    the single cubic (least squares on samples) and the largest distance to the original (mm).
    """
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array1OfPnt
    from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal

    n = len(poles)
    arr = TColgp_Array1OfPnt(1, n)
    for i, p in enumerate(poles):
        arr.SetValue(i + 1, gp_Pnt(*map(float, p)))
    # A clamped uniform knot vector consistent with the pole count; good enough to evaluate.
    inner = n - degree - 1
    if inner < 0:
        return poles, np.inf
    knots = TColStd_Array1OfReal(1, inner + 2)
    mults = TColStd_Array1OfInteger(1, inner + 2)
    for i in range(inner + 2):
        knots.SetValue(i + 1, i / (inner + 1))
        mults.SetValue(i + 1, degree + 1 if i in (0, inner + 1) else 1)
    curve = Geom_BSplineCurve(arr, knots, mults, degree)
    t = np.linspace(0.0, 1.0, 41)
    samples = np.array([[curve.Value(u).X(), curve.Value(u).Y(), curve.Value(u).Z()] for u in t])
    basis = np.stack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3], axis=1)
    inner_rhs = samples - np.outer(basis[:, 0], samples[0]) - np.outer(basis[:, 3], samples[-1])
    mid, *_ = np.linalg.lstsq(basis[:, 1:3], inner_rhs, rcond=None)
    cubic = np.vstack([samples[0], mid, samples[-1]])
    err = float(np.linalg.norm(basis @ cubic - samples, axis=1).max())
    return cubic, err
