"""How well the table of published cars sizes a car from its proportions, each car left out.

:mod:`carbody.fit.size` reads a fitted car's length, width and height in wheelbases against
``carbody/data/car_dimensions.csv`` to give its wheelbase when none is told. Here each car of
the table is left out in turn. Its own proportions, with ``--noise`` (a fraction, each of the
three log proportions, seeded) standing for a fit's error, are sized by the rest. Two models of
the table are compared, both through :func:`carbody.fit.size.estimate_size`:

- **one Gaussian**: every car relabelled one class, so the table is one Gaussian over the log
  dimensions (the shipped model before the classes);
- **a Gaussian per class** (shipped): each class its own, weighted by how well it explains the
  proportions (:attr:`carbody.fit.size.PublishedCars.log_classes`).

Printed per noise level: the median and mean absolute error of the wheelbase and of the length
it gives, and how often the truth lies within two of the estimate's spreads; then the
wheelbase's mean error by class of car. Each proportion is
taken as uncertain as the noise, and never less than the fit's floor
(:attr:`~carbody.policy.FitPolicy.size_proportion_floor`).

Run: python benchmarks/bench_size_table.py [--noise 0 0.02 0.03 0.05] [--seed 0] [--json OUT.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def box_shape(length: float, width: float, height: float) -> np.ndarray:
    """(840,) a shape vector (normalised units) whose curves span a box of these proportions (in
    wheelbases), the height from the ground (a tyre's radius below the wheel centres): what
    :func:`~carbody.fit.size.estimate_size` measures of a wireframe is its extents."""
    from carbody.fit.size import TYRE_RADIUS_NORM

    lo = np.array([0.0, -0.3 * length * 1000, -TYRE_RADIUS_NORM + 50])
    hi = np.array([width * 500, 0.7 * length * 1000, height * 1000 - TYRE_RADIUS_NORM])
    t = np.linspace(0.0, 1.0, 4)[:, None]
    return np.concatenate([lo + t * (hi - lo)] * 70).ravel()


def left_out(cars, i: int, one_class: bool):
    """The table without car ``i`` (every car one class with ``one_class``)."""
    from dataclasses import replace

    rest = cars.without(cars.names[i])
    return replace(rest, classes=("car",) * len(rest.names)) if one_class else rest


def run(noise: float, seed: int) -> dict:
    """{model: {wheelbase/length median and mean abs. error (fractions), within two spreads}}."""
    from carbody.fit.size import estimate_size, published_cars
    from carbody.policy import FIT_POLICY

    cars = published_cars()
    rng = np.random.default_rng(seed)
    jitter = rng.normal(0.0, noise, (len(cars.names), 3))  # the same for both models
    floor = max(noise, FIT_POLICY.size_proportion_floor)  # as the fit: never surer than the policy's floor
    out = {}
    for label, one_class in (("one Gaussian", True), ("a Gaussian per class", False)):
        wb_err, length_err, within, by_class = [], [], [], {}
        for i, (wb, width, height, length) in enumerate(cars.dimensions):
            ratios = np.array([length, width, height]) / wb * np.exp(jitter[i])
            est = estimate_size(box_shape(*ratios), None, floor, left_out(cars, i, one_class))
            e = np.log(est.wheelbase_mm / wb)
            wb_err.append(abs(e))
            length_err.append(abs(np.log(est.dimensions_mm["length"] / length)))
            within.append(abs(e) <= 2 * est.spread)
            by_class.setdefault(cars.classes[i], []).append(abs(e))
        out[label] = {"wheelbase_median": float(np.median(wb_err)), "wheelbase_mean": float(np.mean(wb_err)),
                      "length_median": float(np.median(length_err)), "length_mean": float(np.mean(length_err)),
                      "within_two_spreads": float(np.mean(within)), "cars": len(wb_err),
                      "wheelbase_mean_by_class": {c: float(np.mean(v)) for c, v in by_class.items()}}
    return out


def main(argv: list[str] | None = None) -> int:
    from carbody.fit.size import published_cars

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--noise", type=float, nargs="+", default=[0.0, 0.02, 0.03, 0.05],
                        help="the proportions' error, a fraction (one standard deviation of each log ratio)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    rows = []
    by_class = {}
    print("| proportions' noise | model | wheelbase: median / mean abs. error | length: median / mean abs. error "
          "| truth within two spreads |")
    print("|---|---|---|---|---|")
    for noise in args.noise:
        for label, r in run(noise, args.seed).items():
            rows.append({"noise": noise, "model": label, **r})
            by_class[noise, label] = r["wheelbase_mean_by_class"]
            print(f"| {100 * noise:.0f} % | {label} | {100 * r['wheelbase_median']:.1f} / {100 * r['wheelbase_mean']:.1f} % "
                  f"| {100 * r['length_median']:.1f} / {100 * r['length_mean']:.1f} % | {100 * r['within_two_spreads']:.0f} % |")
    print("\nThe wheelbase's mean abs. error by class of car (one Gaussian / a Gaussian per class):\n")
    cars = published_cars()
    classes = sorted(set(cars.classes), key=lambda c: (-cars.classes.count(c), c))
    print("| proportions' noise | " + " | ".join(f"{c} ({cars.classes.count(c)})" for c in classes) + " |")
    print("|---|" + "---|" * len(classes))
    for noise in args.noise:
        one, per = by_class[noise, "one Gaussian"], by_class[noise, "a Gaussian per class"]
        print(f"| {100 * noise:.0f} % | " + " | ".join(f"{100 * one[c]:.1f} / {100 * per[c]:.1f}" for c in classes) + " |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
