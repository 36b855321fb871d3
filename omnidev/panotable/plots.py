"""Figures written as PNG (matplotlib, Agg backend; imported lazily by the CLI)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from omnidev.atomic import atomic_path
from omnidev.panotable.table import Calibration, radial


def plot_radial_fit(calib: Calibration, path: Path, *, force: bool = False) -> None:
    """Fig. 4.7(b): the fitted radial stretching function with the landmarks on it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = calib.table
    rs, re = table.rho_range
    grid = np.linspace(rs, re, 400)
    fig, (ax, axr) = plt.subplots(
        2, 1, figsize=(7, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    ax.plot(np.degrees(grid), radial(table.coeffs, grid), "-", label="fitted f_r (eq. 4.2)")
    ax.plot(np.degrees(calib.polar.rho), calib.polar.r, "+", ms=10, mew=1.5, label="landmarks")
    ax.set_ylabel("image radius r (px)")
    coeffs = ", ".join(f"{c:.4g}" for c in table.coeffs)
    ax.set_title(f"Radial stretching function  a0..a4 = {coeffs}", fontsize=9)
    ax.legend()
    ax.grid(alpha=0.3)
    axr.axhline(0, color="k", lw=0.5)
    axr.plot(np.degrees(calib.polar.rho), calib.fit.residual_px, "o", ms=4)
    axr.set_xlabel("elevation rho (deg)")
    axr.set_ylabel("residual (px)")
    axr.set_title(f"radial RMS {calib.fit.rms_px:.3f} px", fontsize=9)
    axr.grid(alpha=0.3)
    lim = max(0.5, float(np.max(np.abs(calib.fit.residual_px))) * 1.2)
    axr.set_ylim(-lim, lim)
    axr.set_xlim(math.degrees(rs), math.degrees(re))
    fig.tight_layout()
    with atomic_path(Path(path), force=force) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
