"""The view-angle classifier (paper III.A–B): rendered multi-view data set + MobileNetV2.

- :mod:`carbody.view.labels`: the 24 azimuth classes (the paper's 13 left-side classes and
  their mirror images).
- :mod:`carbody.view.dataset`: render the data set from library bodies (``carbody render-dataset``).
- :mod:`carbody.view.network`: MobileNetV2 in plain torch.
- :mod:`carbody.view.train`: train it (``carbody train-view``).
- :mod:`carbody.view.photo`: photo-like looks for the renders (``render-dataset --photo-like``).
- :mod:`carbody.view.calibrate`: the temperature that calibrates the probabilities (``carbody calibrate-view``).
- :mod:`carbody.view.predict`: tell the view of a picture with the shipped weights (``carbody view``,
  ``--box`` / ``-k`` to crop to the car).

Heavy imports (torch, VTK, OCP) happen inside functions.
"""
from carbody.view.labels import CLASS_ANGLES_DEG, N_CLASSES, class_of, continuous_estimate, mirror_class


def predict_view(image, weights=None, mirror_average: bool = True, box=None, marks=None):
    """See :func:`carbody.view.predict.predict_view`."""
    from carbody.view.predict import predict_view as _predict

    return _predict(image, weights, mirror_average, box=box, marks=marks)


__all__ = ["CLASS_ANGLES_DEG", "N_CLASSES", "class_of", "continuous_estimate", "mirror_class", "predict_view"]
