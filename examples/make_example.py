"""Make the shipped example: a photo of a car that is NOT one of the templates.

A compact crossover is built by the template builder from its own design table, surfaced by our
pipeline, rendered off-screen (VTK) at front 30° with a little elevation by a perspective camera
7 m from the car's centre (a photo taken on the street), and its visible keypoints are marked by
projecting the wireframe through that camera with 1 px of annotation noise. The truth
wireframe is kept so the demo can report the 3D error of the reconstruction.

Run (writes next to this script):  .venv/bin/python examples/make_example.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: The example car: a compact crossover between the hatchbacks and SUVs of the library.
EXAMPLE_CAR = dict(
    name="carbody example crossover", car_class="suv", length=4420.0, width=1830.0, height=1605.0,
    wheelbase=2650.0, front_overhang=890.0, track_front=1585.0, track_rear=1590.0, tyre_radius=345.0,
    ground_clearance=175.0, details={"roof_rear_y": 1.22, "deck_y": 1.29, "cowl_y": 0.29, "nose_h": 0.54},
    source="fictional: carbody example (not a library template)",
)
VIEW_DEG, ELEVATION_DEG = 30.0, 6.0
#: Camera distance from the car's centre, mm: a street photo, close enough for perspective.
CAMERA_DISTANCE_MM = 7000.0
SIZE = (1000, 640)


def main() -> None:
    from carbody.fit import View, visible_keypoints
    from carbody.fit.keypoints_io import keypoint_slots, write_keypoints
    from carbody.fit.solve import car_centre
    from carbody.render.mesh import tessellate
    from carbody.render.scene import Look, Scene, save_png
    from carbody.surface import build_body
    from carbody.templates.design import DesignTable, build_wireframe
    from carbody.view.dataset import FIXED_DETAIL_COLOURS, detail_meshes, wheel_meshes
    from carbody.wireframe import Wireframe, write_wireframe

    design = DesignTable(**EXAMPLE_CAR)
    truth = Wireframe(design.name, build_wireframe(design))
    body = build_body(truth)
    meshes = tessellate(body)
    meshes += wheel_meshes(truth.control_points, design.tyre_radius) + detail_meshes(meshes)
    scene = Scene(meshes, size=SIZE, antialias=3)
    look = Look(paint=(0.55, 0.07, 0.06), glass=(0.12, 0.15, 0.18), background=(0.90, 0.91, 0.93),
                colours=dict(FIXED_DETAIL_COLOURS))
    image = scene.render(VIEW_DEG, ELEVATION_DEG, look=look, distance=CAMERA_DISTANCE_MM, fill=0.82)
    save_png(image, HERE / "car.png")

    slots = keypoint_slots()
    camera = View(VIEW_DEG, ELEVATION_DEG, 0.0, CAMERA_DISTANCE_MM, car_centre(truth.control_points))
    names = visible_keypoints(camera, truth.control_points)
    rng = np.random.default_rng(7)
    points = {}
    for name in names:
        slot = slots[name]
        p = truth.control_points[slot.point_index] * slot.sign
        u, v = scene.project(p[None])[0] + rng.normal(0.0, 1.0, 2)
        points[name] = (round(float(u), 1), round(float(v), 1))
    write_keypoints(HERE / "car_keypoints.json", points, image="car.png", image_size=SIZE)
    write_wireframe(HERE / "car_truth.step", truth, both_halves=True)
    print(f"wrote car.png ({SIZE[0]} x {SIZE[1]}), {len(points)} keypoints, car_truth.step to {HERE}")


if __name__ == "__main__":
    main()
