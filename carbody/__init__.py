"""carbody: one photo of a car -> an editable CAD car body in STEP.

    import carbody
    result = carbody.reconstruct("car.png", "car_keypoints.json")   # view from the classifier
    result.body_cadquery(), result.wireframe_build123d(), result.write("out/")
    edited = result.wireframe.with_curves_moved(["roof_side_1", "roof_side_2"], [0, 0, 40])
    body = carbody.surface_wireframe(edited)          # the body follows the edit

The pipeline, one module per stage: ``topology`` (curves, keypoints, regions as data) ->
``templates`` (real cars, STEP) -> ``library`` (normalised, expanded model matrix S) ->
``view`` (view classifier) -> ``fit`` (keypoints -> wireframe) -> ``surface`` (regions ->
skeleton -> Bezier faces -> shell) -> ``occ`` (the OCCT boundary: STEP in/out, faces, sewing,
checks); ``pipeline`` runs them all. Heavy libraries load on first use, not on import.
"""

__version__ = "0.1.0"


def reconstruct(image, keypoints, view=None, wheelbase_mm=None, **kwargs):
    """Photo + keypoints -> wireframe and body; see :func:`carbody.pipeline.reconstruct`."""
    from carbody.pipeline import reconstruct as run

    return run(image, keypoints, view, wheelbase_mm, **kwargs)


def surface_wireframe(wire, **kwargs):
    """An edited wireframe (or a build123d/CadQuery object of named edges) -> its body, refusing
    one that folds; see :func:`carbody.surface.body.surface_wireframe`."""
    from carbody.surface.body import surface_wireframe as run

    return run(wire, **kwargs)
