"""What the fit believes about the view before it looks at the marks: :class:`ViewPrior`.

The view search (:mod:`carbody.fit.search`) scores every view round the car by how well the
library explains the marks there; the prior adds what is known besides: a view the user told
(a von Mises distribution around its azimuth, a Gaussian around its elevation) or the view
classifier's probabilities over its 24 classes, and, where the roll is freed, a Gaussian around
the roll told (0° unless told: a photo is taken about level). Either is a preference among views
the marks fit about equally well, never a wall: the search still looks everywhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carbody.camera import View
from carbody.policy import FIT_POLICY, FitPolicy

#: Spread (degrees) of each classifier class's share of the prior: the classes are 15° apart.
CLASS_SD_DEG = 10.0


@dataclass(frozen=True)
class ViewPrior:
    """−log prior of a view, nats up to a constant (:meth:`cost`).

    Attributes:
        azimuth_deg: the told azimuth, or None (no told azimuth).
        azimuth_sd_deg: its standard deviation.
        elevation_deg, elevation_sd_deg: the elevation's Gaussian.
        classes_deg, probabilities: the classifier's classes and their probabilities, or None.
        floor: the share of a uniform prior mixed into the classifier's (a confident but wrong
            classifier does not veto a view).
        weight: a factor on the whole −log prior (``FitOptions.view_prior_weight``).
        roll_deg: the roll told (the search keeps it; the fit frees it only where the marks pay
            for it: :func:`carbody.fit.search.with_roll`).
        roll_sd_deg: the roll's Gaussian about ``roll_deg`` (0: not priced, the roll kept).
    """

    azimuth_deg: float | None = None
    azimuth_sd_deg: float = FIT_POLICY.view_prior_sd_deg
    elevation_deg: float = 0.0
    elevation_sd_deg: float = FIT_POLICY.elevation_prior_sd_deg
    classes_deg: tuple[float, ...] | None = None
    probabilities: tuple[float, ...] | None = None
    floor: float = FIT_POLICY.classifier_floor
    weight: float = 1.0
    roll_deg: float = 0.0
    roll_sd_deg: float = 0.0

    @classmethod
    def told(cls, view: View, policy: FitPolicy = FIT_POLICY, weight: float = 1.0) -> "ViewPrior":
        """The prior of a view a user gave (its azimuth and elevation)."""
        return cls(float(view.azimuth) % 360.0, policy.view_prior_sd_deg, float(view.elevation),
                   policy.elevation_prior_sd_deg, weight=weight, roll_deg=float(view.roll))

    @classmethod
    def from_classifier(cls, classes_deg, probabilities, policy: FitPolicy = FIT_POLICY,
                        weight: float = 1.0, elevation_deg: float = 0.0) -> "ViewPrior":
        """The prior of the view classifier's class probabilities."""
        p = np.asarray(probabilities, dtype=float)
        return cls(None, policy.view_prior_sd_deg, float(elevation_deg), policy.elevation_prior_sd_deg,
                   tuple(float(c) for c in classes_deg), tuple(float(v) for v in p / p.sum()),
                   policy.classifier_floor, weight)

    @classmethod
    def uniform(cls, policy: FitPolicy = FIT_POLICY, elevation_deg: float = 0.0,
                roll_deg: float = 0.0) -> "ViewPrior":
        """No view told: every azimuth alike, the elevation and roll a photo's."""
        return cls(None, policy.view_prior_sd_deg, float(elevation_deg), policy.elevation_prior_sd_deg,
                   roll_deg=float(roll_deg))

    @property
    def start(self) -> View:
        """The prior's most likely view (where a view kept as given stands)."""
        if self.azimuth_deg is not None:
            return View(self.azimuth_deg, self.elevation_deg, self.roll_deg)
        if self.probabilities is not None:
            return View(self.classes_deg[int(np.argmax(self.probabilities))], self.elevation_deg, self.roll_deg)
        return View(0.0, self.elevation_deg, self.roll_deg)

    def cost(self, view: View) -> float:
        """−log prior of ``view`` (nats, × ``weight``; 0 at a told view)."""
        if self.weight == 0:
            return 0.0
        nats = 0.5 * ((view.elevation - self.elevation_deg) / self.elevation_sd_deg) ** 2
        if self.roll_sd_deg > 0:
            nats += 0.5 * ((view.roll - self.roll_deg) / self.roll_sd_deg) ** 2
        if self.azimuth_deg is not None:
            kappa = 1.0 / np.radians(self.azimuth_sd_deg) ** 2
            nats += kappa * (1.0 - np.cos(np.radians(view.azimuth - self.azimuth_deg)))
        elif self.probabilities is not None:
            kappa = 1.0 / np.radians(CLASS_SD_DEG) ** 2
            near = np.exp(kappa * (np.cos(np.radians(view.azimuth - np.asarray(self.classes_deg))) - 1.0))
            # (a class's von Mises peak normalised to 1: the floor is a share of the top class's)
            share = (1.0 - self.floor) * float(np.asarray(self.probabilities) @ near) / max(self.probabilities) + self.floor
            nats += -np.log(share)
        return self.weight * float(nats)

    def as_dict(self) -> dict:
        """JSON-ready, for the report."""
        out = {"elevation_deg": self.elevation_deg, "elevation_sd_deg": self.elevation_sd_deg, "weight": self.weight}
        if self.azimuth_deg is not None:
            out.update(kind="told", azimuth_deg=self.azimuth_deg, azimuth_sd_deg=self.azimuth_sd_deg)
        elif self.probabilities is not None:
            top = int(np.argmax(self.probabilities))
            out.update(kind="classifier", top_class_deg=self.classes_deg[top],
                       top_probability=self.probabilities[top], floor=self.floor)
        else:
            out.update(kind="none")
        return out
