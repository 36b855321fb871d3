"""Figures like Figs. 5.13-5.14: error vectors over the screen for each method (PNG).

matplotlib with the Agg backend, imported lazily; written atomically.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from omnidev.atomic import atomic_path
from omnidev.screencal.calibration import ScreenCalibration
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


def plot_calibration(
    calib: ScreenCalibration,
    dots_image: np.ndarray,
    path: Path,
    *,
    lines: int = 10,
    force: bool = True,
) -> None:
    """The calibration over the dot image, no truth needed: the border polygon (yellow),
    the dots found (green) and missed (red crosses), and lines of constant screen x and
    y every 1/``lines`` of the screen, mapped into the image through the calibration's
    inverse (cyan): they should run along the screen's rows and columns of dots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img = np.asarray(dots_image)
    h, w = img.shape[:2]
    sw, sh = calib.screen_size
    fig, ax = plt.subplots(figsize=(10, 10 * h / w))
    ax.imshow(img if img.ndim == 2 else img[..., ::-1], cmap="gray", vmin=0, vmax=255)
    v = np.vstack([calib.border.vertices, calib.border.vertices[:1]])
    ax.plot(v[:, 0], v[:, 1], "-", color="yellow", lw=1)
    found = np.isfinite(calib.dots_image).all(axis=1)
    lay = calib.layout
    ax.plot(calib.dots_image[found, 0], calib.dots_image[found, 1], "+", color="lime", ms=6)
    if lay is not None and (~found).any():
        guess = _screen_to_image(calib, lay.centers[~found])
        ax.plot(guess[:, 0], guess[:, 1], "x", color="red", ms=6)
    t = np.linspace(-0.5, 1, 200)
    for k in range(lines + 1):
        f = k / lines
        for xy in (
            np.column_stack([np.full_like(t, f * sw - 0.5), t * sh]),
            np.column_stack([t * sw, np.full_like(t, f * sh - 0.5)]),
        ):
            xy = xy[(xy[:, 0] >= -0.5) & (xy[:, 1] >= -0.5)]
            xy = xy[(xy[:, 0] <= sw - 0.5) & (xy[:, 1] <= sh - 0.5)]
            uv = _screen_to_image(calib, xy)
            ax.plot(uv[:, 0], uv[:, 1], "-", color="cyan", lw=0.6)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_title(
        f"{calib.method}: {calib.dots_used} dots used; screen grid every 1/{lines}", fontsize=9
    )
    fig.tight_layout()
    with atomic_path(Path(path), force=force) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def _screen_to_image(calib: ScreenCalibration, xy: np.ndarray) -> np.ndarray:
    """Image px of screen points through the calibration's inverse (Newton from a
    homography fitted to the found dots)."""
    from omnidev.screencal.transform import HomographyMap, invert

    found = np.isfinite(calib.dots_image).all(axis=1)
    lay = calib.layout
    if lay is None or found.sum() < 4:
        return np.full((len(xy), 2), np.nan)
    h = HomographyMap.fit(lay.centers[found], calib.dots_image[found])
    start = h(np.asarray(xy, np.float64))
    out: np.ndarray = invert(calib.transform, np.asarray(xy, np.float64), start)
    return out
