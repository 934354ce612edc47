"""Reconstruct the example car and work on it in build123d.

Thickens the skin into a 3 mm solid panel, measures area, volume and size, and exports STEP.
Run:  .venv/bin/python examples/build123d_script.py [OUT_DIR]
"""
import sys
from pathlib import Path

import build123d as bd

import carbody
from carbody.occ.shapes import thicken

HERE = Path(__file__).resolve().parent
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/build123d")
out.mkdir(parents=True, exist_ok=True)

result = carbody.reconstruct(HERE / "car.png", HERE / "car_keypoints.json", view=30)
skin = result.body_build123d()           # build123d.Shell, both halves, mm
wire = result.wireframe_build123d()      # build123d.Compound of Bezier edges
box = skin.bounding_box()
print(f"skin: {type(skin).__name__}, {len(skin.faces())} faces, area {skin.area / 1e6:.2f} m^2")
print(f"size: length {box.size.Y:.0f} mm, width {box.size.X:.0f} mm, height above the wheel centres {box.max.Z:.0f} mm")
print(f"wireframe: {len(wire.edges())} edges, total length {sum(e.length for e in wire.edges()) / 1000:.1f} m")

# Offset the skin 3 mm inwards into a solid panel (the car's sheet metal). build123d's own
# bd.thicken runs OCCT's general offset, which fails on this open shell; carbody's thicken uses
# OCCT's simple offset and hands back a build123d Solid.
panel = thicken(skin, -3.0)
print(f"panel: {type(panel).__name__}, volume {panel.volume / 1e6:.2f} dm^3, valid {panel.is_valid}")

bd.export_step(panel, str(out / "panel.step"))
bd.export_step(wire, str(out / "wireframe.step"))
print(f"wrote {sorted(p.name for p in out.iterdir())} to {out}")
