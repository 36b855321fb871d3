"""Figures like Figs. 5.13-5.14: error vectors over the screen for each method (PNG).

matplotlib with the Agg backend, imported lazily; written atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from omnidev.atomic import atomic_path
from omnidev.screencal.evaluate import MethodErrors


def plot_error_vectors(
    rows: Sequence[MethodErrors],
    path: Path,
    screen_size: tuple[int, int] = (1920, 1080),
    *,
    title: str = "",
    dots: np.ndarray | None = None,
    force: bool = True,
) -> None:
    """One panel per method: the screen (x right, y down, screen px) with each point's
    error vector (estimate - truth) drawn magnified, the panel's magnification and
    RMS / max error in its title; missed points as red crosses; ``dots`` (K, 2)
    screen px of the calibration dots as grey circles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sw, sh = screen_size
    cols = 2 if len(rows) > 1 else 1
    nrows = (len(rows) + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(7.5 * cols, 4.6 * nrows), squeeze=False)
    for ax, r in zip(axes.ravel(), rows, strict=False):
        d = r.estimate - r.truth
        ok = np.isfinite(d).all(axis=1)
        big = float(np.percentile(np.hypot(*d[ok].T), 99)) if ok.any() else 1.0
        gain = 10 ** np.floor(np.log10(0.04 * sw / max(big, 1e-6)))
        ax.set_xlim(-0.5 - 0.04 * sw, sw - 0.5 + 0.04 * sw)
        ax.set_ylim(sh - 0.5 + 0.06 * sh, -0.5 - 0.06 * sh)
        ax.add_patch(
            matplotlib.patches.Rectangle((-0.5, -0.5), sw, sh, fill=False, lw=0.8, ec="0.4")
        )
        if dots is not None:
            ax.plot(dots[:, 0], dots[:, 1], "o", mfc="none", mec="0.6", ms=4)
        ax.quiver(
            r.truth[ok, 0],
            r.truth[ok, 1],
            d[ok, 0] * gain,
            d[ok, 1] * gain,
            angles="xy",
            scale_units="xy",
            scale=1,
            width=0.002,
            color="C0",
        )
        if (~ok).any():
            ax.plot(r.truth[~ok, 0], r.truth[~ok, 1], "x", color="C3", ms=3)
        ax.set_title(
            f"{r.method}: RMS {r.rms:.3f} px, max {r.max:.2f} px, missed {r.missed}"
            f"  (vectors x{gain:g})",
            fontsize=9,
        )
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(rows) :]:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    with atomic_path(Path(path), force=force) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
