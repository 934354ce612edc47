"""The car's size when no wheelbase is told: its proportions read against published cars.

A photo shows a car's shape, not its size. But cars differ less in width and height than in
length and wheelbase, and a car's proportions go with its size: a city car is wide and tall
for its wheelbase, a saloon or a pickup long and low. So the fitted car's length, width and
height *in wheelbases* say how long its wheelbase is likely to be.

The table of published dimensions (``carbody/data/car_dimensions.csv``: length, width,
height and wheelbase of cars of every class, :func:`published_cars`) gives a Gaussian over the
logarithms of (wheelbase, width, height, length) for each class of car: a city car's size goes
with its proportions otherwise than a pickup's or a van's, and one Gaussian for all of them
sizes each car 10–25 % worse, each car of the table left out
(``benchmarks/bench_size_table.py``). The fitted proportions are an observation
of three differences of those logarithms, as uncertain as the fit's posterior says, together
(each never less than :attr:`~carbody.policy.FitPolicy.size_proportion_floor`: the posterior
knows nothing of how real cars differ from the library, nor of the table's own rounding). The
posterior holds the image scale's own uncertainty (:func:`carbody.fit.solve.scale_spread`): a
level front view shows the width against the height but neither against the unseen
wheelbase, so there the two err together. The wheelbase's posterior follows by Gaussian
conditioning in each class, the classes weighted by how well they explain the proportions
(:func:`estimate_size`): a car whose proportions the photo pins is sized by them; one it does
not (a level front view) is sized more by what cars usually are.

This replaces the library mix's own wheelbase (the templates' wheelbases weighted by the mix,
SPEC's default) for the Gaussian-prior methods: on real photos that was 8.6 % off at the
median (docs/real_photos.md), because a mix chosen for its shape takes its size from
whichever templates share that shape, however large they are.
"""
from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from importlib import resources

import numpy as np

from carbody.errors import FitError
from carbody.tolerances import NORMALISED_WHEELBASE
from carbody.topology import load_topology
from carbody.wireframe import sample_curves

#: Published heights stand on the ground, the wireframe on its wheel centres: the tyre's
#: radius in wheelbases joins the fitted height (the templates' tyres: 0.11–0.14, mean 0.12),
#: its spread the height's uncertainty.
TYRE_RADIUS_NORM, TYRE_RADIUS_SPREAD_NORM = 120.0, 10.0

#: Each class's covariance of the log dimensions (:attr:`PublishedCars.log_classes`) is drawn
#: toward this share of the whole table's, weighted as this many cars. Chosen on the table left
#: one car out at a time (``benchmarks/bench_size_table.py``); 2–10 cars and shares 0.25–1 all
#: beat one Gaussian for the whole table.
CLASS_PRIOR_CARS, CLASS_SHRINK = 5.0, 0.5

#: The table's columns, in the order of the Gaussian's axes.
DIMENSIONS = ("wheelbase_mm", "width_mm", "height_mm", "length_mm")

#: The fitted proportions as differences of the log dimensions: log(L/wb), log(W/wb), log(H/wb).
_RATIOS = np.array([[-1.0, 0.0, 0.0, 1.0], [-1.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class PublishedCars:
    """The table of published dimensions.

    Attributes:
        names, classes: per car.
        dimensions: (N, 4) float, mm: wheelbase, width, height, length (:data:`DIMENSIONS`).
    """

    names: tuple[str, ...]
    classes: tuple[str, ...]
    dimensions: np.ndarray

    def without(self, *names: str) -> "PublishedCars":
        """This table less the cars named (each car left out in turn: the benchmarks, the tests).

        Raises:
            FitError: a name not in the table."""
        missing = set(names) - set(self.names)
        if missing:
            raise FitError(f"not in the table of published cars: {', '.join(sorted(missing))}")
        keep = [i for i, n in enumerate(self.names) if n not in names]
        return PublishedCars(tuple(self.names[i] for i in keep), tuple(self.classes[i] for i in keep),
                             self.dimensions[keep])

    @functools.cached_property
    def log_gaussian(self) -> tuple[np.ndarray, np.ndarray]:
        """((4,) mean, (4, 4) covariance) of the log dimensions."""
        logs = np.log(self.dimensions)
        return logs.mean(axis=0), np.cov(logs.T)

    @functools.cached_property
    def log_classes(self) -> list[tuple[str, float, np.ndarray, np.ndarray]]:
        """[(class, share of the table, (4,) mean, (4, 4) covariance)] of the log dimensions, one
        Gaussian per class of two cars or more: a city car's size goes with its proportions
        otherwise than a pickup's. A class's covariance is drawn toward ``CLASS_SHRINK`` × the
        whole table's as if ``CLASS_PRIOR_CARS`` more cars had it (a class of a few cars says
        little of its own spread). A table with no class of two cars is one Gaussian ("all")."""
        logs = np.log(self.dimensions)
        _, whole = self.log_gaussian
        classes = np.asarray(self.classes)
        out = []
        for name in sorted(set(self.classes)):
            own = logs[classes == name]
            n = len(own)
            if n < 2:
                continue
            w = n / (n + CLASS_PRIOR_CARS)
            out.append((name, n / len(logs), own.mean(axis=0), w * np.cov(own.T) + (1.0 - w) * CLASS_SHRINK * whole))
        return out or [("all", 1.0, *self.log_gaussian)]  # (no class of two cars: the table as one)


@functools.lru_cache(maxsize=1)
def published_cars() -> PublishedCars:
    """The shipped table (``carbody/data/car_dimensions.csv``), read once."""
    text = resources.files("carbody.data").joinpath("car_dimensions.csv").read_text(encoding="utf-8")
    rows = list(csv.DictReader(text.splitlines()))
    return PublishedCars(tuple(r["car"] for r in rows), tuple(r["class"] for r in rows),
                         np.array([[float(r[d]) for d in DIMENSIONS] for r in rows]))


@dataclass(frozen=True)
class SizeEstimate:
    """The wheelbase a fitted car's proportions give.

    Attributes:
        wheelbase_mm: the most likely wheelbase.
        spread: one standard deviation of it, as a fraction (of its logarithm).
        prior_spread: the same for a car of unknown proportions (the table's own spread).
        proportions: {"length", "width", "height"}: the fitted car's, in wheelbases.
        proportion_spreads: the same keys: each proportion's uncertainty used, as a fraction.
        proportion_covariance: (3, 3) the proportions' uncertainty used, together (their log
            ratios, in ``proportions``' order): a view pins some of their differences only.
        dimensions_mm, dimension_spreads: {"wheelbase", "width", "height", "length"}: each
            dimension's most likely value (mm) and spread (a fraction), read as the wheelbase is.
        classes: {class of the table: its weight} (they sum to 1, largest first): which kinds
            of car the proportions read as.
        scale_steps: how many standard deviations of the image scale the fitted car is most
            likely off by, as the table reads its proportions (0 without ``scale_move``): the
            fit moves the car back along what the marks cannot tell from the scale
            (:func:`carbody.fit.solve.along_scale`).
        length_move: how far the fit then moved the car's length toward the one in
            ``dimensions_mm``, as a fraction (+: longer; 0 when not moved).
    """

    wheelbase_mm: float
    spread: float
    prior_spread: float
    proportions: dict[str, float]
    proportion_spreads: dict[str, float]
    proportion_covariance: np.ndarray | None = None
    dimensions_mm: dict[str, float] | None = None
    dimension_spreads: dict[str, float] | None = None
    scale_steps: float = 0.0
    classes: dict[str, float] | None = None
    length_move: float = 0.0

    def as_dict(self) -> dict:
        return {"wheelbase_mm": self.wheelbase_mm, "spread_pct": 100.0 * self.spread,
                "prior_spread_pct": 100.0 * self.prior_spread,
                "proportions": self.proportions,
                "proportion_spreads_pct": {k: 100.0 * v for k, v in self.proportion_spreads.items()},
                "dimensions_mm": self.dimensions_mm,
                "dimension_spreads_pct": {k: 100.0 * v for k, v in (self.dimension_spreads or {}).items()},
                "scale_steps": self.scale_steps, "length_move_pct": 100.0 * self.length_move,
                "classes": {k: round(v, 3) for k, v in (self.classes or {}).items()}}


def estimate_size(shape: np.ndarray, keypoint_covariance: np.ndarray | None, floor: float,
                  cars: PublishedCars | None = None, scale_move: np.ndarray | None = None) -> SizeEstimate:
    """The wheelbase of a fitted car from its proportions (module docstring).

    Args:
        shape: (840,) or (280, 3) float, the fitted car's control points, normalised units.
        keypoint_covariance: (105, 105) float, normalised units²: the fit's posterior over the
            35 keypoints' coordinates (:func:`carbody.fit.solve.joint_keypoint_covariance`),
            or None (each proportion then as uncertain as ``floor``).
        floor: the least uncertainty of each proportion, a fraction.
        cars: the table (default the shipped one).
        scale_move: (105,) the keypoints' move per standard deviation of the image scale, the
            share of ``keypoint_covariance`` that the marks cannot tell from the scale
            (:func:`carbody.fit.solve.scale_spread`), or None. Given, :attr:`SizeEstimate.scale_steps`
            says how far along it the table puts the car.
    Raises:
        FitError: a shape with no length, width or height.
    """
    cars = cars or published_cars()
    points = np.asarray(shape, dtype=float).reshape(-1, 3)
    extents = car_extents(points)
    if not (np.all(np.isfinite(extents)) and np.all(extents > 0)):
        raise FitError("the fitted car has no length, width or height to size it by")
    noise = np.diag(np.full(3, floor ** 2))
    noise[2, 2] += (TYRE_RADIUS_SPREAD_NORM / extents[2]) ** 2
    if keypoint_covariance is not None:
        J = extent_rows(points) / extents[:, None]
        noise += J @ keypoint_covariance @ J.T
    variance = np.diagonal(noise)
    observed = np.log(extents / NORMALISED_WHEELBASE)
    u = None if scale_move is None or keypoint_covariance is None else J @ scale_move  # per scale SD
    post_mean, post_cov, steps, weights = _class_posterior(cars.log_classes, observed, noise, u)
    keys = ("length", "width", "height")
    spread, prior_spread = float(np.sqrt(post_cov[0, 0])), float(np.sqrt(cars.log_gaussian[1][0, 0]))
    return SizeEstimate(wheelbase_mm=float(np.exp(post_mean[0])), spread=spread, prior_spread=prior_spread,
                        proportions={k: float(v) for k, v in zip(keys, extents / NORMALISED_WHEELBASE)},
                        proportion_spreads={k: float(v) for k, v in zip(keys, np.sqrt(variance))},
                        proportion_covariance=noise,
                        dimensions_mm={k.removesuffix("_mm"): float(np.exp(m)) for k, m in zip(DIMENSIONS, post_mean)},
                        dimension_spreads={k.removesuffix("_mm"): float(np.sqrt(v))
                                           for k, v in zip(DIMENSIONS, np.diagonal(post_cov))},
                        scale_steps=steps,
                        classes=dict(sorted(((c[0], float(w)) for c, w in zip(cars.log_classes, weights)),
                                            key=lambda kv: -kv[1])))


def _class_posterior(classes: list[tuple[str, float, np.ndarray, np.ndarray]], observed: np.ndarray,
                     noise: np.ndarray, move: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The log dimensions' posterior given the fitted proportions ``observed`` (3,) (log ratios,
    :data:`_RATIOS`) with their uncertainty ``noise`` (3, 3), over the table's classes
    (:attr:`PublishedCars.log_classes`): each class conditioned as a Gaussian, weighted by how
    well it explains the proportions. Returns the mixture's (4,) mean and (4, 4) covariance, and
    how many standard deviations of the image scale the proportions most likely lie off: the
    mixture's log-likelihood's slope along ``move`` (3,), the proportions' move per standard
    deviation of the scale (0 without); and each class's weight (k,)."""
    means, covs, logs, slopes = [], [], [], []
    for _, share, mean, cov in classes:
        marginal = np.linalg.inv(_RATIOS @ cov @ _RATIOS.T + noise)  # of the observed proportions
        residual = observed - _RATIOS @ mean
        gain = cov @ _RATIOS.T @ marginal
        means.append(mean + gain @ residual)
        covs.append(cov - gain @ _RATIOS @ cov)
        logs.append(np.log(share) - 0.5 * residual @ marginal @ residual + 0.5 * np.linalg.slogdet(marginal)[1])
        slopes.append(0.0 if move is None else -float(move @ marginal @ residual))
    weights = np.exp(np.array(logs) - max(logs))
    weights /= weights.sum()
    mean = np.einsum("k,kd->d", weights, np.array(means))
    spread = np.array(means) - mean
    cov = np.einsum("k,kde->de", weights, np.array(covs)) + np.einsum("k,kd,ke->de", weights, spread, spread)
    return mean, cov, float(weights @ np.array(slopes)), weights


def car_extents(points: np.ndarray) -> np.ndarray:
    """(3,) the length, width and height of a car's control points (280, 3), as the size reads
    them: its curves' extents (both halves' width; the height from the ground, a tyre's radius
    below the wheel centres), the points' units."""
    samples = sample_curves(np.asarray(points, dtype=float).reshape(-1, 3), 64).reshape(-1, 3)
    return np.array([np.ptp(samples[:, 1]), 2.0 * samples[:, 0].max(), samples[:, 2].max() + TYRE_RADIUS_NORM])


def extent_rows(points: np.ndarray) -> np.ndarray:
    """(3, 105): the length, width and height as differences of keypoint coordinates — the
    keypoints furthest front and back, out and up — whose posterior spreads stand for the
    extents' (the extents themselves are of curve samples between keypoints)."""
    idx = load_topology().keypoint_point_indices
    kp = points[idx]
    J = np.zeros((3, 3 * len(idx)))
    J[0, 3 * int(np.argmax(kp[:, 1])) + 1] += 1.0
    J[0, 3 * int(np.argmin(kp[:, 1])) + 1] -= 1.0
    J[1, 3 * int(np.argmax(kp[:, 0]))] = 2.0
    J[2, 3 * int(np.argmax(kp[:, 2])) + 2] = 1.0
    return J
