"""``carbody freecad OUT_DIR -o car.FCStd``: a reconstruction as a FreeCAD document.

Runs FreeCAD's own ``freecadcmd`` (FreeCAD has its own OCCT build) with the workbench's headless
core: the photo as an image plane lined up with the fitted camera, the car as parametric
objects: one curve object per wireframe curve with editable poles, the sewn body recomputed from
them (``CarBody``, by this same ``carbody``), and one object per region.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from carbody.errors import CarbodyError
from carbody.outputs import FREECAD, check_not_inputs, check_output_file, staged
from carbody.shipped import WORKBENCH

_SCRIPT = """
import json, os, sys
sys.path.insert(0, {workbench!r})
import FreeCAD
from carbody_wb import core
out, target = {out!r}, {target!r}
doc = FreeCAD.newDocument("carbody")
report = json.load(open(os.path.join(out, "report.json")))
image = report.get("image") if report.get("image") and os.path.isfile(report["image"]) else None
try:
    wire, body, _ = core.import_reconstruction(doc, image, out)
except core.CarbodyWorkbenchError as exc:
    print("CARBODY-ERROR " + str(exc))
    sys.exit(2)
if image and core.line_up_photo(doc, image, report) is None:
    core.add_photo(doc, image)
doc.saveAs(target)
print("CARBODY " + json.dumps({{"curves": len(wire.Group), "body_objects": len(body.Group)}}))
"""


class FreeCADError(CarbodyError):
    """FreeCAD is missing or could not build the document."""


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("freecad", help="turn a reconstruction folder into a FreeCAD document (.FCStd)")
    p.add_argument("folder", type=Path, help="a folder written by `carbody reconstruct`")
    p.add_argument("-o", "--output", required=True, type=Path, help="the .FCStd file to write")
    p.add_argument("--freecadcmd", default="freecadcmd", help="FreeCAD's command-line program (default: freecadcmd)")
    p.set_defaults(func=run_freecad)


def run_freecad(args: argparse.Namespace) -> int:
    from carbody.inputs import read_json
    from carbody.progress import progress

    inputs = {f"the folder's {name}": args.folder / name for name in ("wireframe.step", "body.step", "report.json")}
    check_not_inputs({"--output": args.output}, inputs)
    check_output_file(args.output, FREECAD)
    exe = args.freecadcmd if os.path.isabs(args.freecadcmd) else shutil.which(args.freecadcmd)
    if not exe or not os.path.isfile(exe):
        raise FreeCADError(f"FreeCAD is not installed: {args.freecadcmd!r} not found "
                           "(Debian: apt-get install freecad-python3)")
    for path in inputs.values():
        if not path.is_file():
            raise FreeCADError(f"{args.folder}: no {path.name} (not a `carbody reconstruct` folder)")
    report = read_json(args.folder / "report.json", "reconstruction report", FreeCADError)
    if not isinstance(report, dict) or not isinstance(report.get("image"), (str, type(None))):
        raise FreeCADError(f"{args.folder / 'report.json'}: not a `carbody reconstruct` report")
    check_not_inputs({"--output": args.output}, {"the photo": report.get("image")})
    with progress(("FreeCAD",), args.quiet) as bar, staged([args.output]) as at, \
            tempfile.TemporaryDirectory(prefix="carbody-fc-") as tmp:
        bar.start("FreeCAD")
        target = at(args.output)
        script = Path(tmp) / "build.py"
        script.write_text(_SCRIPT.format(workbench=str(WORKBENCH), out=str(args.folder.resolve()),
                                         target=str(target)))
        env = {**os.environ, "CARBODY_COMMAND": os.environ.get("CARBODY_COMMAND", f"{sys.executable} -m carbody")}
        proc = subprocess.run([exe, str(script)], capture_output=True, text=True, env=env)
        result = [line for line in proc.stdout.splitlines() if line.startswith("CARBODY ")]
        failed = [line for line in proc.stdout.splitlines() if line.startswith("CARBODY-ERROR ")]
        if failed:
            raise FreeCADError(f"FreeCAD could not build the document: {failed[0][len('CARBODY-ERROR '):]}")
        if not result or not target.is_file():
            lines = [line for line in (proc.stdout + proc.stderr).splitlines() if "carbody" in line.lower() or "Error" in line]
            raise FreeCADError(f"FreeCAD could not build the document: {lines[-1] if lines else 'no result'}")
    counts = json.loads(result[0][len("CARBODY "):])
    print(f"wrote {args.output}: {counts['curves']} curve objects, {counts['body_objects']} body objects")
    return 0
