"""The one place for tolerances and units.

Lengths are millimetres unless a name says ``_norm`` (normalised library units, wheelbase = 1000).
"""

#: Wheelbase of a normalised library model (paper II.E).
NORMALISED_WHEELBASE = 1000.0

#: Two curve ends closer than this (mm) are the same junction.
JUNCTION_TOL_MM = 1e-3

#: Control points written to STEP are rounded to this (mm), so they survive the text format exactly.
STEP_ROUND_MM = 1e-6

#: A coordinate read from STEP further than this from the origin (mm; 100 m) is no car's: refused
#: before its squares overflow in the checks that follow.
MAX_COORDINATE_MM = 1e5

#: A curve read from STEP whose poles differ from a cubic Bezier by more than this is refused.
CUBIC_TOL_MM = 1e-6

#: Dimensions of a built template must match its design table within this fraction.
DIMENSION_REL_TOL = 0.01

# ---- surfaces (carbody.surface, carbody.occ.faces/sewing/checks)

#: Boundary sample spacing of the skeleton algorithm, normalised units (paper IV.B; ~50 mm).
SKELETON_SPACING_NORM = 20.0

#: A region loop whose consecutive curves are further apart than this (mm) does not close.
LOOP_CLOSE_TOL_MM = 1e-3

#: A region whose area (in 3D, or projected onto its best-fit plane) is below this fraction of
#: its perimeter squared is degenerate.
DEGENERATE_AREA_REL = 1e-4

#: A curve shorter than this fraction of its region's perimeter, or two junctions of a region's
#: loop closer than it, is degenerate (the templates' shortest curve is 5e-3 of its perimeter).
DEGENERATE_LENGTH_REL = 1e-4

#: Sewing tolerance (mm); faces are built to meet exactly, so this only absorbs rounding.
SEW_TOL_MM = 1e-3

#: Required after sewing: largest edge/vertex tolerance, wireframe-to-face distance (mm).
SHELL_TOL_MM = 0.01

#: Inner patch edges of a region must meet within this normal angle (degrees; CATIA default G1).
G1_TOL_DEG = 0.5

#: A region folds when faces covering more than this share of its area have turned back over
#: themselves (carbody.surface.folds; the templates' wheel arches reach 0.7 %).
FOLD_AREA_SHARE = 0.02
