"""carbody: one photo of a car -> an editable CAD car body in STEP.

The pipeline, one module per stage: ``topology`` (curves, keypoints, regions as data) ->
``templates`` (14 real cars, STEP) -> ``library`` (normalised, expanded model matrix S) ->
``fit`` (keypoints -> wireframe) -> ``surface`` (regions -> skeleton -> Bezier faces -> shell)
-> ``occ`` (the OCCT boundary: STEP in/out, faces, sewing, checks).
"""

__version__ = "0.1.0"
