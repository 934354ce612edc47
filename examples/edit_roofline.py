"""Edit a car's wireframe in Python and let the body follow: raise the roof line by 40 mm.

Every curve of the roof (its centre line, its sides, the windshield's top edge and the rear
window's) moves up 40 mm; the pillars and window frames that meet them stretch up with them
(shared curve ends stay joined, the car stays mirror-symmetric), and the body is surfaced again.
A region folded by an edit is refused in one line naming it and its curves (``FoldError``).

Run:  .venv/bin/python examples/edit_roofline.py [OUT_DIR] [--wireframe WIRE.step]
(default: reconstruct the example photo; ``--wireframe`` edits any wireframe file instead, e.g.
a ``carbody reconstruct`` folder's ``wireframe.step`` or one saved back from FreeCAD).
"""
import argparse
from pathlib import Path

import carbody
from carbody.surface.body import write_body
from carbody.topology import load_topology
from carbody.wireframe import read_wireframe, write_wireframe

HERE = Path(__file__).resolve().parent
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("out", nargs="?", default="out/edit_roofline", type=Path)
parser.add_argument("--wireframe", type=Path, help="the wireframe to edit (default: reconstruct examples/car.png)")
parser.add_argument("--raise-mm", type=float, default=40.0)
args = parser.parse_args()
args.out.mkdir(parents=True, exist_ok=True)

if args.wireframe:
    wire = read_wireframe(args.wireframe)
else:
    wire = carbody.reconstruct(HERE / "car.png", HERE / "car_keypoints.json", view=30).wireframe

roof = [load_topology().curves[i].name for i, _ in load_topology().region("roof").loop]
raised = wire.with_curves_moved(roof, [0.0, 0.0, args.raise_mm])
body = carbody.surface_wireframe(raised)          # FoldError if the edit folds a region

before = wire.keypoints()["roof_front_corner"][2]
after = raised.keypoints()["roof_front_corner"][2]
shell = body.report["shell"]
print(f"roof curves raised: {', '.join(roof)}")
print(f"roof front corner: z {before:.1f} -> {after:.1f} mm; body: {shell['faces']} faces, valid {shell['valid']}, "
      f"folds {len(body.report['folds'])}")
write_wireframe(args.out / "wireframe_raised.step", raised, both_halves=True)
write_body(args.out / "body_raised.step", body)
print(f"wrote {sorted(p.name for p in args.out.iterdir())} to {args.out}")
