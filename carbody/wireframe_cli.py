"""``carbody wireframe IN -o OUT``: a wireframe from STEP to JSON or back (both halves).

The JSON holds every curve's name, end junctions and poles (mm): what a script or the FreeCAD
workbench edits; the STEP is what CAD systems open, one named part per curve. Either file, or
one saved by FreeCAD, CadQuery or build123d with the curves named, reads back with
``carbody surface``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("wireframe", help="convert a wireframe between STEP and JSON (both halves)",
                       description="Read a wireframe (STEP from carbody, FreeCAD, CadQuery or build123d with "
                                   "named curves, or carbody's wireframe JSON) and write it as STEP or JSON, "
                                   "both halves, checked: every curve named, cubic and joined.")
    p.add_argument("input", type=Path, help="wireframe .step/.stp or .json")
    p.add_argument("-o", "--output", type=Path, required=True, help="wireframe .step/.stp or .json to write")
    p.set_defaults(func=_convert)


def _convert(args) -> int:
    from carbody.errors import OutputError
    from carbody.outputs import check_output_file
    from carbody.wireframe import read_wireframe, write_wireframe, write_wireframe_json

    suffix = args.output.suffix.lower()
    if suffix not in (".json", ".step", ".stp"):
        raise OutputError(f"{args.output}: a wireframe is written as .step, .stp or .json")
    check_output_file(args.output)
    wf = read_wireframe(args.input)
    if suffix == ".json":
        write_wireframe_json(args.output, wf, both_halves=True)
    else:
        write_wireframe(args.output, wf, both_halves=True)
    print(f"wrote {args.output}: {wf.name}", file=sys.stderr)
    return 0
