"""``carbody parts FILE.step``: the named curves and faces of a carbody STEP file, with centres.

Other programs (the FreeCAD workbench) read a carbody STEP file with their own reader and use
this listing to name what they read, matching by position rather than by order.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from carbody.errors import CarbodyError


class PartsError(CarbodyError):
    """A STEP file whose named parts cannot be listed."""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("parts", help="list the named curves and faces of a carbody STEP file")
    p.add_argument("step", type=Path, help="a wireframe or body STEP file written by carbody")
    p.add_argument("--json", action="store_true", help="print JSON (default: a table)")
    p.set_defaults(func=_parts)


def curve_centre(poles: np.ndarray, samples: int = 64) -> list[float]:
    """Arc-length centroid of a polynomial Bezier curve with (n, 3) poles, mm."""
    from math import comb

    n = len(poles) - 1
    t = np.linspace(0.0, 1.0, samples)[:, None]
    basis = np.hstack([comb(n, i) * t**i * (1 - t) ** (n - i) for i in range(n + 1)])
    pts = basis @ poles
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    mids = (pts[1:] + pts[:-1]) / 2
    return (seg @ mids / seg.sum()).tolist() if seg.sum() > 0 else pts[0].tolist()


def face_region(name: str) -> str:
    """Region of a body face named ``REGION_K`` or ``REGION_right_K``."""
    stem = name.rsplit("_", 1)[0] if name.rsplit("_", 1)[-1].isdigit() else name
    return stem[: -len("_right")] if stem.endswith("_right") else stem


def face_entry(name: str, face, colour=None) -> dict:
    """{name, region, centre (mm), area (mm^2), colour} of one named body face (``colour``: sRGB
    0..1 as the file colours it, None when it does not)."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    c = props.CentreOfMass()
    return {"name": name, "region": face_region(name), "centre": [c.X(), c.Y(), c.Z()], "area": props.Mass(),
            "colour": None if colour is None else [float(v) for v in colour]}


def body_faces(body) -> list[dict]:
    """:func:`face_entry` of every face of a :class:`carbody.surface.Body`, as written to STEP."""
    from carbody.surface.body import face_names, region_colour

    return [face_entry(n, f, region_colour(p.region)) for n, p, (_, f) in zip(face_names(body), body.patches, body.faces)]


def list_parts(path: Path) -> dict:
    """{product, curves: [{name, centre, poles}], faces: [{name, region, centre, area, colour}]} of a
    STEP file carbody writes: a wireframe, a body, or the assembly of both (``car.step``).

    Raises:
        PartsError: the file is unreadable, or names no curve and no face.
    """
    from carbody.occ.step_body import read_body_step
    from carbody.occ.step_curves import read_curves_step

    try:
        body = read_body_step(path)
        product, curves = read_curves_step(path)
    except CarbodyError as exc:
        raise PartsError(str(exc)) from None
    faces = [face_entry(name, face, colour) for name, colour, face in body.faces]
    named = [c for c in curves if c.name and len(c.poles)]
    if not named and not faces:
        raise PartsError(f"{path}: names no curve and no face (not a STEP file carbody wrote, or its names "
                         "were lost on saving)")
    return {"product": body.product or product, "faces": faces,
            "curves": [{"name": c.name, "centre": curve_centre(c.poles), "poles": c.poles.tolist()} for c in named]}


def _parts(args) -> int:
    listing = list_parts(args.step)
    if args.json:
        print(json.dumps(listing))
    else:
        print(f"{listing['product']}: {len(listing['curves'])} curves, {len(listing['faces'])} faces")
        for c in listing["curves"]:
            print(f"  curve {c['name']}")
        for f in listing["faces"]:
            print(f"  face  {f['name']} ({f['region']})")
    return 0
