"""STEP in and out for named curves (the wireframe), through OCCT.

Each curve is written as its own named ``GEOMETRIC_CURVE_SET`` holding one B-spline (a cubic
Bezier is a one-span B-spline), in millimetres, AP214, with the product named after the car.
Reading finds curves by name on any named STEP representation item (curve set, edge, curve) or
XCAF label, so a file saved back by another CAD system that keeps the names reads as well.
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

    Args:
        path: output file (written atomically).
        curves: (name, poles) pairs or :class:`NamedCurve`; poles (n, 3) float, mm. Poles are
            rounded to :data:`~carbody.tolerances.STEP_ROUND_MM` so they survive the text format.
        product_name: the STEP product name (the car).
    Returns:
        the written path.
    """
    from OCP.BRep import BRep_Builder
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDataStd import TDataStd_Name
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopoDS import TopoDS_Compound
    from OCP.XCAFDoc import XCAFDoc_DocumentTool

    _init_step_statics()
    items = [c if isinstance(c, NamedCurve) else NamedCurve(c[0], np.asarray(c[1], float)) for c in curves]
    doc = TDocStd_Document(TCollection_ExtendedString("XmlXCAF"))
    shape_tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    builder = BRep_Builder()
    compound = TopoDS_Compound()
    builder.MakeCompound(compound)
    edges = []
    for item in items:
        poles = np.round(np.asarray(item.poles, float) / STEP_ROUND_MM) * STEP_ROUND_MM
        edge = bezier_edge(poles)
        builder.Add(compound, edge)
        edges.append(edge)
    label = shape_tool.AddShape(compound, False)
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(product_name))
    for item, edge in zip(items, edges):
        sub = shape_tool.AddSubShape(label, edge)
        TDataStd_Name.Set_s(sub, TCollection_ExtendedString(item.name))

    return write_step_document(path, doc, TemplateError)


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


def read_curves_step(path: str | Path) -> tuple[str, list[NamedCurve]]:
    """Read every curve of a STEP file with the name the file gives it.

    Names are taken from named curve sets, named edges and named curves. Curves are returned
    in millimetres whatever the file's length unit.

    Returns:
        (product name, curves in file order); curves the file leaves unnamed come last, named "".
    Raises:
        TemplateError: the file is missing, not a regular file, too large or not a readable STEP
            file, or a control point lies further than :data:`~carbody.tolerances.MAX_COORDINATE_MM`.
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.StepBasic import StepBasic_Product
    from OCP.StepData import StepData_Factors
    from OCP.STEPControl import STEPControl_Reader
    from OCP.StepGeom import StepGeom_Curve
    from OCP.StepShape import StepShape_EdgeCurve, StepShape_GeometricCurveSet
    from OCP.StepToGeom import StepToGeom
    from OCP.TColStd import TColStd_SequenceOfAsciiString

    from carbody.occ.shapes import sub_shapes

    from carbody.inputs import MAX_STEP_BYTES, input_file

    path = input_file(path, "STEP file", TemplateError, MAX_STEP_BYTES)
    _init_step_statics()
    reader = STEPControl_Reader()
    try:
        ok = reader.ReadFile(str(path)) == IFSelect_RetDone and reader.TransferRoots() > 0
    except Exception:  # OCCT raises Standard_Failure on some garbage
        ok = False
    if not ok:
        raise TemplateError(f"{path}: not a readable STEP file")
    units, angles, solids = (TColStd_SequenceOfAsciiString() for _ in range(3))
    reader.FileUnits(units, angles, solids)
    unit = units.Value(1).ToCString().upper() if units.Length() else "MM"
    factors = StepData_Factors()
    factors.InitializeFactors(_LENGTH_UNITS_MM.get(unit, 1.0), 1.0, 1.0)

    product = ""
    curves: list[NamedCurve] = []
    model = reader.StepModel()
    for i in range(1, model.NbEntities() + 1):
        entity = model.Value(i)  # OCP hands back the most derived type
        if not product and isinstance(entity, StepBasic_Product):
            product = entity.Name().ToCString()
            continue
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
            curve = _geom_curve(geom, name, reversed_)
            near = np.all(np.abs(curve.poles) <= MAX_COORDINATE_MM, axis=1)  # NaN is not near either
            if not near.all():
                far = curve.poles[~near][0]
                raise TemplateError(f"{path}: curve {name!r} has a control point at {far.tolist()} mm, "
                                    f"further than any car's ({MAX_COORDINATE_MM:g} mm from the origin)")
            curves.append(curve)
    n_edges = len(sub_shapes(reader.OneShape(), "edge"))
    curves += [NamedCurve("", np.zeros((0, 3)))] * max(0, n_edges - len(curves))
    return product, curves


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
