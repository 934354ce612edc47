"""Nelder–Mead over a few view angles, step for step as ``scipy.optimize.minimize(method="Nelder-Mead")``.

The view search refines its candidates with scipy's Nelder–Mead (non-adaptive, no bounds, an
initial simplex, ``xatol``/``fatol``/``maxfev``). Importing ``scipy.optimize`` costs a fresh
process about 0.2 s of CPU (0.5 s of wall time on a loaded machine), more than a photo's
refinements themselves; this is the same algorithm with the same arithmetic in the same order
(scipy 1.17's ``_minimize_neldermead``, BSD licence), so the points it visits and the one it
returns are scipy's, bit for bit (``tests/test_nelder_mead.py`` compares them).
"""
from __future__ import annotations

from typing import Callable

import numpy as np


class _OutOfEvaluations(Exception):
    pass


def nelder_mead(fun: Callable[[np.ndarray], float], simplex: np.ndarray, xatol: float = 1e-4,
                fatol: float = 1e-4, maxfev: int | None = None) -> np.ndarray:
    """The best vertex Nelder–Mead finds from ``simplex``.

    Args:
        fun: the objective of an (N,) float point (inf where it is not defined).
        simplex: (N + 1, N) float, the initial simplex.
        xatol, fatol: stop when every vertex lies within ``xatol`` of the best in every
            coordinate and within ``fatol`` of its value.
        maxfev: most evaluations (default 200 N).
    Returns:
        (N,) float, the best vertex (scipy's ``result.x``).
    """
    sim = np.asarray(np.atleast_2d(simplex).copy(), dtype=float)
    n = sim.shape[1]
    if sim.ndim != 2 or sim.shape[0] != n + 1:
        raise ValueError("the initial simplex must be (N + 1, N)")
    rho, chi, psi, sigma = 1, 2, 0.5, 0.5
    if maxfev is None:
        maxfun = maxiter = n * 200
    else:
        maxfun, maxiter = maxfev, (n * 200 if maxfev == np.inf else np.inf)
    calls = [0]

    def func(x: np.ndarray) -> float:
        if calls[0] >= maxfun:
            raise _OutOfEvaluations
        calls[0] += 1
        fx = fun(np.copy(x))
        return fx if np.isscalar(fx) else np.asarray(fx).item()

    fsim = np.full((n + 1,), np.inf, dtype=float)
    try:
        for k in range(n + 1):
            fsim[k] = func(sim[k])
    except _OutOfEvaluations:
        pass
    finally:
        ind = np.argsort(fsim)
        sim = np.take(sim, ind, 0)
        fsim = np.take(fsim, ind, 0)
    ind = np.argsort(fsim)
    fsim = np.take(fsim, ind, 0)
    sim = np.take(sim, ind, 0)

    iterations = 1
    while calls[0] < maxfun and iterations < maxiter:
        try:
            if (np.max(np.ravel(np.abs(sim[1:] - sim[0]))) <= xatol
                    and np.max(np.abs(fsim[0] - fsim[1:])) <= fatol):
                break
            xbar = np.add.reduce(sim[:-1], 0) / n
            xr = (1 + rho) * xbar - rho * sim[-1]
            fxr = func(xr)
            shrink = False
            if fxr < fsim[0]:
                xe = (1 + rho * chi) * xbar - rho * chi * sim[-1]
                fxe = func(xe)
                if fxe < fxr:
                    sim[-1], fsim[-1] = xe, fxe
                else:
                    sim[-1], fsim[-1] = xr, fxr
            elif fxr < fsim[-2]:
                sim[-1], fsim[-1] = xr, fxr
            else:
                if fxr < fsim[-1]:  # contraction outside
                    xc = (1 + psi * rho) * xbar - psi * rho * sim[-1]
                    fxc = func(xc)
                    if fxc <= fxr:
                        sim[-1], fsim[-1] = xc, fxc
                    else:
                        shrink = True
                else:  # contraction inside
                    xcc = (1 - psi) * xbar + psi * sim[-1]
                    fxcc = func(xcc)
                    if fxcc < fsim[-1]:
                        sim[-1], fsim[-1] = xcc, fxcc
                    else:
                        shrink = True
                if shrink:
                    for j in range(1, n + 1):
                        sim[j] = sim[0] + sigma * (sim[j] - sim[0])
                        fsim[j] = func(sim[j])
            iterations += 1
        except _OutOfEvaluations:
            pass
        ind = np.argsort(fsim)
        sim = np.take(sim, ind, 0)
        fsim = np.take(fsim, ind, 0)
    return sim[0]
