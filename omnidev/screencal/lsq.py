"""A small Levenberg-Marquardt solver (numpy only) for the screen-calibration models."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def levenberg_marquardt(
    fun: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    *,
    iterations: int = 100,
    rel_step: float = 1e-6,
) -> FloatArray:
    """Minimise ``sum(fun(x)**2)`` from ``x0`` with a forward-difference Jacobian.

    Returns the parameters; stops when a step no longer lowers the cost by 1e-12
    relative or after ``iterations`` accepted or rejected steps.
    """
    x = np.asarray(x0, np.float64).copy()
    r = fun(x)
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(iterations):
        h = rel_step * np.maximum(np.abs(x), 1e-3)
        jac = np.empty((len(r), len(x)))
        for k in range(len(x)):
            xk = x.copy()
            xk[k] += h[k]
            jac[:, k] = (fun(xk) - r) / h[k]
        jtj = jac.T @ jac
        g = jac.T @ r
        improved = False
        while lam < 1e12:
            a = jtj + lam * np.diag(np.maximum(np.diag(jtj), 1e-12))
            try:
                step = np.linalg.solve(a, -g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            xn = x + step
            rn = fun(xn)
            cn = float(rn @ rn)
            if np.isfinite(cn) and cn < cost:
                done = cost - cn <= 1e-12 * max(cost, 1e-300)
                x, r, cost = xn, rn, cn
                lam = max(lam / 10, 1e-12)
                improved = not done
                break
            lam *= 10
        if not improved:
            break
    return x
