"""The view search's Nelder–Mead visits the points scipy's does and returns scipy's answer."""
import numpy as np
import pytest

from carbody.fit.nelder_mead import nelder_mead


def _rosenbrock(x):
    return float(np.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2))


def _walled(x):  # inf outside a box, as the search's objective is past its range
    return np.inf if np.any(np.abs(x) > 1.5) else float(np.sum((x - 0.3) ** 2) + 0.1 * np.sin(7 * x[0]))


def _flat(x):  # ties everywhere: the sort's order decides
    return float(np.round(np.sum(x ** 2), 1))


@pytest.mark.parametrize("fun", [_rosenbrock, _walled, _flat])
@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("maxfev, xatol", [(5, 0.5), (14, 0.5), (40, 0.05), (400, 1e-6), (None, 1e-4)])
def test_the_same_points_as_scipy(fun, dim, maxfev, xatol):
    from scipy.optimize import minimize

    rng = np.random.default_rng(dim)
    x = rng.uniform(-1.2, 1.2, dim)
    simplex = np.vstack([x] + [x + [2.0, 2.0, 0.1][i] * np.eye(dim)[i] for i in range(dim)])
    ours, theirs = [], []
    options = {"initial_simplex": simplex, "xatol": xatol, "fatol": 1e-2}
    if maxfev is not None:
        options["maxfev"] = maxfev
    found = minimize(lambda p: theirs.append(p.copy()) or fun(p), x, method="Nelder-Mead", options=options)
    best = nelder_mead(lambda p: ours.append(p.copy()) or fun(p), simplex, xatol=xatol, fatol=1e-2, maxfev=maxfev)
    assert len(ours) == len(theirs) and all(np.array_equal(a, b) for a, b in zip(ours, theirs))
    assert np.array_equal(best, found.x)
