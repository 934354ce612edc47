"""Hard but plausible wireframes for testing the surface stage, made from the library alone.

A fitted car is a mix of library models moved by a smooth displacement field
(:mod:`carbody.fit.deform`); on real photos such a car can leave the library's span far enough
that a region's outline folds in its best-fit plane. These generators make such cars without
any photo, each from a seed, in four kinds:

* ``extrapolated``: two or three templates mixed with weights that sum to 1 but reach outside
  [0, 1] (a car "beyond" its templates);
* ``displaced``: a mix of library models moved by the fit's own displacement field (its broad
  and local parts, carried by the curve ends) drawn at several times its prior amplitude;
* ``proportions``: a template stretched or squashed far past the library's expansion: height
  above the wheel centres, width, front and rear overhangs;
* ``pinched``: a template whose greenhouse is squashed toward the belt line (thin side windows,
  a nearly flat windshield).

Every kind keeps the wheel centres where the library puts them and the curves joined (the
library's normalised frame, scaled to the mean template wheelbase).
"""
from __future__ import annotations

import numpy as np

from carbody.library import Library
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import Topology, load_topology
from carbody.wireframe import Wireframe

KINDS = ("extrapolated", "displaced", "proportions", "pinched")


_FIELDS: dict[int, object] = {}


def _field(library: Library, topology: Topology):
    """The fit's displacement field around the library's mean car (cached per library)."""
    from carbody.fit.deform import DeformationField

    if id(library) not in _FIELDS:
        _FIELDS[id(library)] = DeformationField.around(library.S.mean(axis=1).reshape(-1, 3), topology)
    return _FIELDS[id(library)]


def _templates(library: Library) -> np.ndarray:
    """(T, 280, 3) normalised control points of every template's own model."""
    return np.array([library.points(library.original(t)) for t in range(len(library.template_names))])


def extrapolated(library: Library, rng: np.random.Generator, spread: float = 0.8) -> np.ndarray:
    """Two or three templates mixed by weights summing to 1, ~N(1/k, spread) each."""
    cars = _templates(library)
    k = int(rng.integers(2, 4))
    pick = rng.choice(len(cars), k, replace=False)
    w = rng.normal(0.0, spread, k)
    w += 1.0 / k - w.mean()
    return np.tensordot(w, cars[pick], axes=1)


def displaced(library: Library, rng: np.random.Generator, amplitude: float | None = None,
              topology: Topology | None = None) -> np.ndarray:
    """A mix of four library models moved by the fit's displacement field at ``amplitude``
    (default: drawn in [1, 5]) times its prior standard deviation."""
    topo = topology or load_topology()
    field = _field(library, topo)
    pick = rng.choice(library.n_models, 4, replace=False)
    mix = np.tensordot(rng.dirichlet(np.ones(4)), np.array([library.points(j) for j in pick]), axes=1)
    amplitude = rng.uniform(1.0, 5.0) if amplitude is None else amplitude
    d = field.basis @ rng.normal(size=field.basis.shape[1]) + field.local @ rng.normal(size=field.local.shape[1])
    return mix + amplitude * d.reshape(-1, 3)


def proportions(library: Library, rng: np.random.Generator, topology: Topology | None = None) -> np.ndarray:
    """A template with height (above the wheel centres) and width each x [0.4, 1.8] and each
    overhang x [0.5, 1.6], about its own boundary point as in the library's expansion."""
    topo = topology or load_topology()
    cars = _templates(library)
    cp = cars[rng.integers(len(cars))].copy()
    fz, fx, ff, fr = rng.uniform(0.4, 1.8), rng.uniform(0.4, 1.8), rng.uniform(0.5, 1.6), rng.uniform(0.5, 1.6)
    cp[:, 2] = np.where(cp[:, 2] > 0, cp[:, 2] * fz, cp[:, 2])
    cp[:, 0] *= fx
    y_front = cp[topo.junction_point_index(topo.overhang_boundaries["front"]), 1]
    y_rear = cp[topo.junction_point_index(topo.overhang_boundaries["rear"]), 1]
    y = cp[:, 1]
    cp[:, 1] = np.where(y < y_front, y_front + ff * (y - y_front), np.where(y > y_rear, y_rear + fr * (y - y_rear), y))
    return cp


def pinched(library: Library, rng: np.random.Generator, topology: Topology | None = None) -> np.ndarray:
    """A template whose points above the belt line move toward it by a factor in [0.01, 0.4]."""
    topo = topology or load_topology()
    cars = _templates(library)
    cp = cars[rng.integers(len(cars))].copy()
    belt = cp[topo.junction_point_index("b_pillar_belt"), 2]
    f = rng.uniform(0.01, 0.4)
    cp[:, 2] = np.where(cp[:, 2] > belt, belt + f * (cp[:, 2] - belt), cp[:, 2])
    return cp


def stress_wireframe(library: Library, seed: int, kind: str | None = None,
                     topology: Topology | None = None) -> Wireframe:
    """One hard wireframe (mm, at the templates' mean wheelbase), reproducible from its seed.

    Args:
        library: the model library (:func:`carbody.library.load_library`).
        seed: the random seed.
        kind: one of :data:`KINDS`; by default ``KINDS[seed % 4]``.
    """
    kind = KINDS[seed % len(KINDS)] if kind is None else kind
    rng = np.random.default_rng(seed)
    if kind == "extrapolated":
        cp = extrapolated(library, rng)
    elif kind == "displaced":
        cp = displaced(library, rng, topology=topology)
    elif kind == "proportions":
        cp = proportions(library, rng, topology)
    elif kind == "pinched":
        cp = pinched(library, rng, topology)
    else:
        raise ValueError(f"unknown kind {kind!r} (known: {', '.join(KINDS)})")
    wheelbase = float(np.mean(library.template_wheelbase_mm))
    return Wireframe(f"{kind} {seed}", cp * wheelbase / NORMALISED_WHEELBASE)
