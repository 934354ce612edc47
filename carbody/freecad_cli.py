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
    w = sub.add_parser("freecad-workbench", help="link the FreeCAD workbench into FreeCAD's Mod folder",
                       description="Link the carbody workbench this carbody ships into FreeCAD's Mod "
                                   "folder (as the link MOD/carbody). Through the link the workbench "
                                   "finds this carbody's virtual environment, so its commands run this "
                                   "carbody. Restart FreeCAD to see it.")
    w.add_argument("--mod-dir", type=Path, default=None,
                   help="FreeCAD's Mod folder (default: the one FreeCAD reads, asked of freecadcmd)")
    w.add_argument("--freecadcmd", default="freecadcmd", help="FreeCAD's command-line program (default: freecadcmd)")
    w.set_defaults(func=run_freecad_workbench)


def freecad_mod_dir(freecadcmd: str = "freecadcmd") -> Path:
    """The Mod folder FreeCAD reads the user's addons from (``getUserAppDataDir()/Mod``).

    Raises:
        FreeCADError: FreeCAD is not installed or does not say.
    """
    exe = _freecadcmd(freecadcmd)
    with tempfile.TemporaryDirectory(prefix="carbody-fc-") as tmp:
        script = Path(tmp) / "where.py"
        script.write_text("import FreeCAD\nprint('CARBODY-DIR ' + FreeCAD.getUserAppDataDir())\n")
        proc = subprocess.run([exe, str(script)], capture_output=True, text=True)
    found = [line[len("CARBODY-DIR "):] for line in proc.stdout.splitlines() if line.startswith("CARBODY-DIR ")]
    if not found:
        raise FreeCADError("FreeCAD did not say where its Mod folder is: give it with --mod-dir")
    return Path(found[0]) / "Mod"


def link_workbench(mod_dir: Path) -> Path:
    """Link the shipped workbench into ``mod_dir`` as ``carbody`` (made if missing; an earlier
    link replaced); returns the link.

    Raises:
        FreeCADError: ``mod_dir/carbody`` is a folder or file of its own (left as it is), or the
            link cannot be made.
    """
    link = Path(mod_dir) / "carbody"
    target = WORKBENCH.resolve()
    if link.exists() and not link.is_symlink():
        raise FreeCADError(f"{link} is already there and is not a link: move it away first")
    try:
        link.parent.mkdir(parents=True, exist_ok=True)
        if link.is_symlink():
            link.unlink()
        link.symlink_to(target, target_is_directory=True)
    except OSError as exc:
        raise FreeCADError(f"{link}: cannot link the workbench ({exc.strerror or exc})") from None
    return link


def run_freecad_workbench(args: argparse.Namespace) -> int:
    mod_dir = args.mod_dir if args.mod_dir is not None else freecad_mod_dir(args.freecadcmd)
    link = link_workbench(mod_dir)
    print(f"linked {link} -> {WORKBENCH.resolve()}: restart FreeCAD and pick the carbody workbench")
    return 0


def _freecadcmd(name: str) -> str:
    exe = name if os.path.isabs(name) else shutil.which(name)
    if not exe or not os.path.isfile(exe):
        raise FreeCADError(f"FreeCAD is not installed: {name!r} not found "
                           "(Debian: apt-get install freecad-python3)")
    return exe


def run_freecad(args: argparse.Namespace) -> int:
    from carbody.inputs import read_json
    from carbody.progress import progress

    inputs = {f"the folder's {name}": args.folder / name for name in ("wireframe.step", "body.step", "report.json")}
    check_not_inputs({"--output": args.output}, inputs)
    check_output_file(args.output, FREECAD)
    exe = _freecadcmd(args.freecadcmd)
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
