"""Reconstruct the example car and work on it in CadQuery.

Cuts a sunroof into the roof and enlarges the front wheel opening, measures the skin, and
exports STEP and STL.  Run:  .venv/bin/python examples/cadquery_script.py [OUT_DIR]
"""
import sys
from pathlib import Path

import cadquery as cq

import carbody

HERE = Path(__file__).resolve().parent
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/cadquery")
out.mkdir(parents=True, exist_ok=True)

result = carbody.reconstruct(HERE / "car.png", HERE / "car_keypoints.json", view=30)
body = result.body_cadquery()            # cq.Shell, both halves, mm
wire = result.wireframe_cadquery()       # cq.Compound of 125 Bezier edges
kp = result.wireframe.keypoints()        # {name: [x, y, z]} of the left half, mm
print(f"body: {type(body).__name__}, {len(body.Faces())} faces, area {body.Area() / 1e6:.2f} m^2, valid {body.isValid()}")
print(f"wireframe: {len(wire.Edges())} edges")

# A sunroof: a 700 x 500 mm box through the roof, centred between the roof's front and rear.
front, rear = kp["roof_front_centre"], kp["roof_rear_centre"]
y_mid, z_top = (front[1] + rear[1]) / 2, max(front[2], rear[2])
sunroof = cq.Solid.makeBox(500, 700, 400, cq.Vector(-250, y_mid - 350, z_top - 250))
# A larger front wheel opening: a cylinder across the car at the front wheel centre (y = 0, z = 0).
arch_top = kp["front_arch_top"][2]
opening = cq.Solid.makeCylinder(arch_top + 40, 3000, cq.Vector(-1500, 0, 0), cq.Vector(1, 0, 0))
cut = body.cut(sunroof).cut(opening)
print(f"after the cuts: area {cut.Area() / 1e6:.2f} m^2 (removed {(body.Area() - cut.Area()) / 1e6:.3f} m^2), valid {cut.isValid()}")

cq.exporters.export(cut, str(out / "body_cut.step"))
cq.exporters.export(cut, str(out / "body_cut.stl"), tolerance=2.0)
cq.exporters.export(wire, str(out / "wireframe.step"))
print(f"wrote {sorted(p.name for p in out.iterdir())} to {out}")
