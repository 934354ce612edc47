"""Single-view wireframe fitting (paper III.C–E): photo + keypoints + view → 3D wireframe.

Public API::

    from carbody.fit import fit_wireframe, read_keypoints, visible_keypoints, View
    ann = read_keypoints("car.json")                    # project JSON, COCO or labelme
    result = fit_wireframe(ann.points, 30, image_size=ann.image_size,
                           camera_distance_mm="auto")   # 30°: a prior; every view is searched
    result.wireframe                                    # carbody.wireframe.Wireframe, mm
    result.view, result.residuals_px(), result.keypoints_mm()
    result.diagnostics.rejected, result.diagnostics.renamed   # marks left out, names exchanged

Modules: :mod:`~carbody.camera` (the SPEC camera and eq. 1), :mod:`~carbody.fit.keypoints_io`
(annotation files, names, checks), :mod:`~carbody.fit.options` (how to fit),
:mod:`~carbody.fit.single_view` (the whole stage, the algorithm in a page),
:mod:`~carbody.fit.solve` (the weight solve), :mod:`~carbody.fit.shape_prior` (the shape
prior), :mod:`~carbody.fit.hypothesis` (the one score of a view and the marks it explains),
:mod:`~carbody.fit.search` (the view search), :mod:`~carbody.fit.robust` (misplaced marks and
twin names), :mod:`~carbody.fit.view_prior`, :mod:`~carbody.fit.visibility` (what a view can
see), :mod:`~carbody.fit.fit_camera` (pinhole, told distance, a turn toward an off-centre car),
:mod:`~carbody.fit.checks` (a closer camera), :mod:`~carbody.fit.deform` (onto the marks),
:mod:`~carbody.fit.result` and :mod:`~carbody.fit.diagnostics` (what it returns),
:mod:`~carbody.fit.overlay` and :mod:`~carbody.fit.report` (outputs), :mod:`~carbody.fit.cli`
(``carbody fit``); thresholds in :mod:`carbody.policy`.
"""
from carbody.camera import View, eq1_angles, eq1_rotation, project, view_rotation
from carbody.fit.diagnostics import FitDiagnostics, RejectedMark
from carbody.fit.keypoints_io import Annotation, check_keypoints, keypoint_slots, read_keypoints
from carbody.fit.options import FitOptions
from carbody.fit.result import FitResult
from carbody.fit.single_view import fit_wireframe
from carbody.fit.view_prior import ViewPrior
from carbody.fit.visibility import visible_keypoints

__all__ = [
    "Annotation", "FitDiagnostics", "FitOptions", "FitResult", "RejectedMark", "View", "ViewPrior",
    "check_keypoints", "eq1_angles", "eq1_rotation", "fit_wireframe", "keypoint_slots", "project",
    "read_keypoints", "view_rotation", "visible_keypoints",
]
