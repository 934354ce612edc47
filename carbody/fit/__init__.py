"""Single-view wireframe fitting (paper III.C–E): photo + keypoints + view → 3D wireframe.

Public API::

    from carbody.fit import fit_wireframe, read_keypoints, visible_keypoints, View
    ann = read_keypoints("car.json")                    # project JSON, COCO or labelme
    result = fit_wireframe(ann.points, 30, image_size=ann.image_size,
                           camera_distance_mm="auto")   # a photo: find the camera's distance
    result.wireframe                                    # carbody.wireframe.Wireframe, mm
    result.view, result.residuals_px(), result.keypoints_mm()

Modules: :mod:`~carbody.camera` (the SPEC camera and eq. 1), :mod:`~carbody.fit.keypoints_io`
(annotation files, names, checks), :mod:`~carbody.fit.visibility` (what a view can see),
:mod:`~carbody.fit.solve` (the weight solve), :mod:`~carbody.fit.refine` (view refinement),
:mod:`~carbody.fit.shape_prior` (the shape prior), :mod:`~carbody.fit.single_view` (the whole
stage), :mod:`~carbody.fit.result` (what it returns), :mod:`~carbody.fit.overlay` and
:mod:`~carbody.fit.report` (outputs), :mod:`~carbody.fit.cli` (``carbody fit``).
"""
from carbody.camera import View, eq1_angles, eq1_rotation, project, view_rotation
from carbody.fit.keypoints_io import Annotation, check_keypoints, keypoint_slots, read_keypoints
from carbody.fit.result import FitResult
from carbody.fit.single_view import fit_wireframe
from carbody.fit.visibility import visible_keypoints

__all__ = [
    "Annotation", "FitResult", "View", "check_keypoints", "eq1_angles", "eq1_rotation",
    "fit_wireframe", "keypoint_slots", "project", "read_keypoints", "view_rotation",
    "visible_keypoints",
]
