"""The one place for tolerances and units.

Lengths are millimetres unless a name says ``_norm`` (normalised library units, wheelbase = 1000).
"""

#: Wheelbase of a normalised library model (paper II.E).
NORMALISED_WHEELBASE = 1000.0

#: Two curve ends closer than this (mm) are the same junction.
JUNCTION_TOL_MM = 1e-3

#: Control points written to STEP are rounded to this (mm), so they survive the text format exactly.
STEP_ROUND_MM = 1e-6

#: A curve read from STEP whose poles differ from a cubic Bezier by more than this is refused.
CUBIC_TOL_MM = 1e-6

#: Dimensions of a built template must match its design table within this fraction.
DIMENSION_REL_TOL = 0.01
