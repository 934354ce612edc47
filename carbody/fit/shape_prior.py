"""The fit's shape prior, built once per library: the Gaussian shape models (sized in mm when
the wheelbase is told), the local displacement field solved inside them, and the charge on a
fitted car wider, longer or taller than any template.

:func:`carbody.fit.single_view.fit_wireframe` reads everything here; nothing here fits.
"""
from __future__ import annotations

import numpy as np

from carbody.fit.deform import DeformationField, joint_field_basis
from carbody.fit.solve import KeypointBasis, ShapeModel, keypoint_spread
from carbody.library import Library
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import load_topology

#: Library preparations kept per process (keypoint rows, shape models), keyed by the S array.
_PREPARED: dict[tuple, object] = {}


def prepared(library: Library, method: str, wheelbase_mm: float | None = None, field: bool = True,
             field_scale: float = 1.0):
    """The library's :class:`KeypointBasis` (``"paper"``) or :class:`ShapeModel` (``"gauss"``),
    built once per library and method; told the car's wheelbase, the shape model of cars sized
    in mm (:func:`sized_shape_model`). The shape models carry the local deformation field
    (``JOINT_FIELD_AMPLITUDE`` × ``field_scale``) unless ``field`` is False (the library's span
    alone)."""
    method = "gauss" if method == "mixture" else method  # same shape model
    idx = load_topology().keypoint_point_indices
    if method == "paper":
        return _cached(library, method, lambda: KeypointBasis.from_shapes(library.S, idx))
    if wheelbase_mm is None:
        key = (method,)
        model = _cached(library, method, lambda: ShapeModel.from_shapes(
            library.S, idx, groups=library.template_index, keep=real_widths(library)), store=True)
    else:
        key = ("sized", float(wheelbase_mm))
        model = _cached(library, key, lambda: sized_shape_model(library, wheelbase_mm))
    if not field:
        return model
    return _cached(library, key + ("field", float(field_scale)),
                   lambda: model.with_field(float(field_scale) * _joint_field(library)))


#: The local part of the photo-matching deformation (:mod:`carbody.fit.deform`: features moved
#: along the car) joins the Gaussian shape prior at this fraction of its amplitude, correlated
#: right across the car (:func:`~carbody.fit.deform.joint_field_basis`), solved with the mix. A
#: car's pillar or window end that sits off every template's is then taken up there, not by
#: bending the whole mix (on a near-side view, a car made 10 % wider moves such a point in the
#: image as well). Chosen on the leave-one-out benchmark (docs/fit_accuracy.md; ``bench_fit_accuracy.py
#: --joint-field A`` reruns 0.2–0.7: larger lowers the level mean, raises the 10° one and the
#: pickup's max; the broad part instead was worse); the deformation after the fit is unchanged.
JOINT_FIELD_AMPLITUDE = 0.3


#: Fraction of the joint field's variance at the keypoints its basis keeps.
JOINT_FIELD_ENERGY = 0.999


def _joint_field(library: Library) -> np.ndarray:
    """(840, q') the local deformation field's basis at ``JOINT_FIELD_AMPLITUDE``, turned to
    the directions that move the keypoints (the solve sees nothing else; the rest would stay at
    their prior mean, 0), strongest first, to ``JOINT_FIELD_ENERGY``."""
    if JOINT_FIELD_AMPLITUDE == 0:
        return np.zeros((library.S.shape[0], 0))

    def build() -> np.ndarray:
        topology = load_topology()
        field = JOINT_FIELD_AMPLITUDE * joint_field_basis(library_mean(library), topology)
        at_keypoints = field.reshape(-1, 3, field.shape[1])[topology.keypoint_point_indices]
        _, sv, Wt = np.linalg.svd(at_keypoints.reshape(-1, field.shape[1]), full_matrices=False)
        keep = int(np.searchsorted(np.cumsum(sv**2) / np.sum(sv**2), JOINT_FIELD_ENERGY)) + 1
        return field @ Wt[:keep].T

    return _cached(library, ("joint field", JOINT_FIELD_AMPLITUDE), build, store=True)


def _cached(library: Library, what, build, store: bool = False):
    """``build()``, once per library (keyed by its S array) and ``what``; with ``store``, once
    per library and code version, on disk (:mod:`carbody.fit.prepared_store`)."""
    key = (id(library.S), library.S.shape, what)
    if key not in _PREPARED:
        if len(_PREPARED) > 64:
            _PREPARED.clear()
        _PREPARED[key] = (library.S, _stored(library, what, build) if store else build())
    return _PREPARED[key][1]


def _stored(library: Library, what, build):
    """``build()``, read from the disk store when it holds this library's ``what``."""
    from carbody.fit.prepared_store import read_stored, stored_path, write_stored

    path = stored_path(library.digest, what)
    value = None if path is None else read_stored(path, what, {"ShapeModel": ShapeModel,
                                                                "DeformationField": DeformationField})
    if value is None:
        value = build()
        if path is not None:
            write_stored(path, what, value)
    return value


#: Which coordinates (x, y, z) of a car the shape model told the wheelbase knows in mm rather
#: than in wheelbases: the width and the height (a car is 1.7–2.0 m wide and about as tall as its
#: class, whatever its wheelbase), not the length (overhangs and cabin grow with the wheelbase).
SIZED_IN_MM = (True, False, True)

#: The width expansions the Gaussian shape models are built from: the library's run 0.7–1.2 ×
#: each template's width, far wider and narrower than real cars differ; those within this
#: range keep the prior's width spread a real car's (docs/fit_accuracy.md: all did worse, 1.0 alone
#: worse at 10° elevation). The paper's solve mixes all of them.
REAL_WIDTH_FACTORS = (0.9, 1.1)


def real_widths(library: Library) -> np.ndarray | None:
    """(N,) bool: the library's models whose width factor lies within REAL_WIDTH_FACTORS
    (None: none does, a library without such expansions; use all)."""
    width = library.factors[:, 3]
    keep = (width >= REAL_WIDTH_FACTORS[0] - 1e-9) & (width <= REAL_WIDTH_FACTORS[1] + 1e-9)
    return keep if keep.any() else None


def sized_shape_model(library: Library, wheelbase_mm: float) -> ShapeModel:
    """The shape model for a car of a known wheelbase, in normalised units.

    The library's models are normalised to a wheelbase of 1000, which also scales their widths
    and heights by 1000 / their own wheelbase: the pickup (3.7 m) comes out narrow and low, the
    roadster (2.3 m) wide and tall, so a prior in those units is loose exactly where a view
    cannot see — the width on a side view, the size on a front one, and on a level view the
    width that trades against the azimuth. Here the principal components are taken with widths
    and heights in mm (``SIZED_IN_MM``) and lengths in wheelbases, then read at this car's
    wheelbase (both from the models of :func:`real_widths`). A wrong
    wheelbase therefore changes the car's shape, not only its size. Measured on the
    leave-one-out benchmark (docs/fit_accuracy.md).
    """
    in_mm = np.tile(SIZED_IN_MM, library.S.shape[0] // 3)

    def build() -> ShapeModel:
        S = np.where(in_mm[:, None], library.S * (library.model_wheelbase_mm / NORMALISED_WHEELBASE), library.S)
        return ShapeModel.from_shapes(S, load_topology().keypoint_point_indices, groups=library.template_index,
                                      keep=real_widths(library))

    model = _cached(library, "sized", build, store=True)
    unit = np.where(in_mm, NORMALISED_WHEELBASE / wheelbase_mm, 1.0)
    mean = model.mean * unit
    size = keypoint_spread(mean.reshape(-1, 3)[load_topology().keypoint_point_indices])
    return ShapeModel(mean=mean, basis=model.basis * unit[:, None], size=size, to_weights=model.to_weights,
                      group_means=model.group_means, weight_offset=model.weight_offset)


#: The scale (a fraction of the bound passed) on which a view is charged for a fitted car wider
#: or narrower, longer or shorter, taller or lower than every template (see :func:`implausibility`).
EXTENT_TOLERANCE = 0.02


def implausibility(shape: np.ndarray, library: Library, wheelbase_mm: float | None = None) -> float:
    """What a view is charged (nats, added to its evidence) for a fitted car whose overall
    width, length or height lies outside the range of the templates' own cars (the published
    ones, not their expansions, which reach 0.7 × the width): ½·Σ(excess / (EXTENT_TOLERANCE ×
    bound))², in wheelbases and, with the wheelbase told, in mm as well.

    The Gaussian prior lets a car seen almost side-on (or head-on) be fitted at a steeper
    elevation as a far narrower (shorter) car: the width moves the marks by sin(elevation),
    and a few prior standard deviations of width (the expansions span 0.7–1.2 ×) cost less than a few
    pixels of misfit on a car unlike the library's. No car is 0.6 m wide; this says so.
    Within the range nothing changes. The range and EXTENT_TOLERANCE were chosen on the
    leave-one-out benchmark (docs/fit_accuracy.md); a wider range (templates ± 10 %) did worse.
    """
    extents = _extents(np.asarray(shape, dtype=float)[:, None])[:, 0]
    low, high = _cached(library, "extents", lambda: _template_extents(library))
    charge = _excess(extents, low[0], high[0])
    if wheelbase_mm is not None:
        charge += _excess(extents * (wheelbase_mm / NORMALISED_WHEELBASE), low[1], high[1])
    return charge


def _extents(S: np.ndarray) -> np.ndarray:
    """(3, N): overall width (both halves), length and height of (840, N) shape vectors."""
    P = S.reshape(-1, 3, S.shape[1])
    return np.stack([2.0 * P[:, 0].max(axis=0), np.ptp(P[:, 1], axis=0), np.ptp(P[:, 2], axis=0)])


def _template_extents(library: Library) -> tuple[np.ndarray, np.ndarray]:
    """((2, 3) lowest, (2, 3) highest) width, length and height of the templates' own models,
    in wheelbases (row 0, normalised units) and in mm (row 1)."""
    cols = np.flatnonzero(np.all(library.factors == 1.0, axis=1))
    if not len(cols):  # a library without its templates' own models: all of them
        cols = np.arange(library.S.shape[1])
    e = _extents(np.asarray(library.S[:, cols], dtype=float))
    both = np.stack([e, e * (library.model_wheelbase_mm[cols] / NORMALISED_WHEELBASE)])
    return both.min(axis=2), both.max(axis=2)


def _excess(values: np.ndarray, low: np.ndarray, high: np.ndarray) -> float:
    """½·Σ((how far each value lies outside [low, high]) / (EXTENT_TOLERANCE × the bound))²."""
    below, above = np.maximum(low - values, 0.0) / low, np.maximum(values - high, 0.0) / high
    return float(0.5 * np.sum(((below + above) / EXTENT_TOLERANCE) ** 2))


def prepared_field(library: Library) -> DeformationField:
    """The photo-matching deformation field around the library's mean model, built once."""
    return _cached(library, "field", lambda: DeformationField.around(library_mean(library), load_topology()),
                   store=True)


def library_mean(library: Library) -> np.ndarray:
    """(840,) float, the library's mean shape vector (normalised units), computed once."""
    key = (id(library.S), library.S.shape, "mean")
    if key not in _PREPARED:
        _PREPARED[key] = (library.S, library.S.mean(axis=1, dtype=np.float64))
    return _PREPARED[key][1]
