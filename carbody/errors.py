"""Typed exceptions: every bad input the API refuses raises one of these.

The CLI turns any :class:`CarbodyError` into one line on stderr and exit code 2.
"""


class CarbodyError(ValueError):
    """Base class: a bad input, named in one line."""


class TopologyError(CarbodyError):
    """The wireframe topology data is inconsistent."""


class TemplateError(CarbodyError):
    """A template (design table or STEP file) is missing, corrupt or mis-structured."""


class LibraryError(CarbodyError):
    """The model library cannot be built from the templates."""


class RenderError(CarbodyError):
    """A shape cannot be rendered (no faces, bad view, bad size or colour)."""


class ViewError(CarbodyError):
    """The view-angle classifier cannot read an image, a data set or its weights."""


class FitError(CarbodyError):
    """Single-view fitting cannot run on the given input (view, keypoints, library)."""


class FitRefused(FitError):
    """The fit ran but explains the marks badly (:func:`carbody.fit.report.refusal_line`): no
    wireframe is given out unless forced (``force=True``, ``--force``). ``partial``, when set,
    is what was made before the refusal (a :class:`carbody.pipeline.Reconstruction` without a
    body), so that its overlay and report can still be written."""


class AngleError(FitError):
    """A view angle given to the fit is not a number or lies outside its range."""


class KeypointError(FitError):
    """Keypoint annotations are unreadable, unknown, too few, degenerate, NaN or off the image."""


class ImageError(CarbodyError):
    """An image file cannot be read."""


class SurfaceError(CarbodyError):
    """A region of the wireframe cannot be surfaced (open loop, zero-length curves, coincident
    junctions, zero area)."""


class RegionLayoutError(SurfaceError):
    """The paper's layout of one region (best-fit plane projection -> skeleton -> ribs) fails on
    this wireframe: its outline folds in the plane, or its ribs cross. :func:`carbody.surface.build_body`
    then lays the region out from its boundary curves alone
    (:mod:`carbody.surface.arc_layout`); only a caller of the paper's stages on their own sees it."""


class FoldError(SurfaceError):
    """A region of an edited wireframe folds: its faces turn back over themselves, or its outline
    crosses itself (:mod:`carbody.surface.folds`). The body can still be had with
    ``allow_folds=True``; the message names the region and its curves."""


class OutputError(CarbodyError):
    """An output file or folder cannot be written (no such folder, no permission, wrong type)."""


class BatchError(CarbodyError):
    """A batch cannot run: its manifest is unreadable or mis-structured, two rows write one
    folder, another batch holds the output folder, or the Dask cluster cannot be reached or
    does not share the output folder."""


class AnnotationError(CarbodyError):
    """The annotation page cannot start (a port that cannot be listened on)."""
