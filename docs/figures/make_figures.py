"""Draw docs/figures/conventions.png, the figure of docs/conventions.md.

Run from the repository root::

    .venv/bin/python docs/figures/make_figures.py

Panels:
    (a) the camera frame in 3D: mirror above, camera below looking up, a scene
        point P with its azimuth theta and elevation rho;
    (b) the omni-image: u/v axes, image center (u0, v0), a pixel at radius r
        and angle phi, the cut-off circle;
    (c) a panorama: columns go clockwise seen from above, row 0 is the top;
    (d) pixel coordinates: (0, 0) is the center of the top-left pixel.

The numbers drawn (P's angles, its panorama position) are computed here with
the same formulas as omnidev.views, so the figure cannot drift from the code.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Circle, FancyArrowPatch, Rectangle

OUT = Path(__file__).resolve().with_name("conventions.png")

AXIS_COLOR = {"x": "#c62828", "y": "#2e7d32", "z": "#1565c0"}
THETA_COLOR = "#ef6c00"
RHO_COLOR = "#6a1b9a"
POINT_COLOR = "#000000"

# The scene point of panel (a), in the camera frame (x, y, z).
P = np.array([1.0, 2.0, -0.7])
P_THETA = math.atan2(P[1], P[0])
P_RHO = math.atan2(P[2], math.hypot(P[0], P[1]))


def arrow(
    ax: Axes,
    a: tuple[float, float],
    b: tuple[float, float],
    color: str,
    *,
    lw: float = 1.8,
    arrowstyle: str = "-|>",
    **kw: Any,
) -> None:
    """A straight arrow from a to b in data coordinates."""
    ax.add_patch(
        FancyArrowPatch(a, b, arrowstyle=arrowstyle, mutation_scale=14, color=color, lw=lw, **kw)
    )


# --------------------------------------------------------------------------- (a) 3D camera frame


def view_basis(az_deg: float = 30.0, el_deg: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """Screen right and screen up vectors of an orthographic view from azimuth/elevation."""
    az, el = math.radians(az_deg), math.radians(el_deg)
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    up = np.array([-math.cos(az) * math.sin(el), -math.sin(az) * math.sin(el), math.cos(el)])
    return right, up


RIGHT, UP = view_basis()


def proj(p: np.ndarray) -> np.ndarray:
    """(..., 3) camera-frame points to (..., 2) drawing coordinates."""
    p = np.asarray(p, np.float64)
    return np.stack([p @ RIGHT, p @ UP], axis=-1)


def line3(ax: Axes, pts: np.ndarray, **kw: object) -> None:
    q = proj(np.asarray(pts))
    ax.plot(q[:, 0], q[:, 1], **kw)  # type: ignore[arg-type]


def arrow3(ax: Axes, a: np.ndarray, b: np.ndarray, color: str, **kw: Any) -> None:
    pa, pb = proj(a), proj(b)
    arrow(ax, (pa[0], pa[1]), (pb[0], pb[1]), color, **kw)


def text3(ax: Axes, p: np.ndarray, s: str, **kw: object) -> None:
    q = proj(p)
    ax.text(q[0], q[1], s, **kw)  # type: ignore[arg-type]


def panel_camera_frame(ax: Axes) -> None:
    ax.set_title("(a) camera frame: origin $O_m$, z up", loc="left")
    t = np.linspace(0, 2 * math.pi, 200)

    # Horizontal plane through O_m (faint disc) for depth.
    ring = np.stack([2.3 * np.cos(t), 2.3 * np.sin(t), 0 * t], 1)
    q = proj(ring)
    ax.fill(q[:, 0], q[:, 1], color="#eceff1", zorder=0)
    ax.plot(q[:, 0], q[:, 1], color="#b0bec5", lw=0.8, zorder=0)
    text3(
        ax,
        np.array([2.2 * math.cos(2.1), 2.2 * math.sin(2.1), 0.0]),
        "plane z = 0",
        color="#78909c",
        fontsize=8.5,
        ha="right",
        va="bottom",
    )

    # Mirror: a convex bowl above the camera, drawn by its rim and profile.
    rim_z, rim_r, apex_z = 0.42, 0.55, -0.14
    rim = np.stack([rim_r * np.cos(t), rim_r * np.sin(t), rim_z + 0 * t], 1)
    prof_r = np.linspace(-rim_r, rim_r, 60)
    prof_z = apex_z + (rim_z - apex_z) * (prof_r / rim_r) ** 2
    for ang in np.linspace(0, math.pi, 7)[:-1]:
        pts = np.stack([prof_r * math.cos(ang), prof_r * math.sin(ang), prof_z], 1)
        line3(ax, pts, color="#90a4ae", lw=0.7, zorder=1)
    line3(ax, rim, color="#546e7a", lw=1.4, zorder=1)
    text3(
        ax,
        np.array([0.0, rim_r + 0.05, rim_z]),
        "mirror",
        color="#546e7a",
        fontsize=9,
        ha="left",
        va="bottom",
    )

    # Camera below, looking up.
    cam_z = -1.35
    box = np.array(
        [
            [-0.14, -0.14, cam_z - 0.25],
            [0.14, -0.14, cam_z - 0.25],
            [0.14, 0.14, cam_z - 0.25],
            [-0.14, 0.14, cam_z - 0.25],
            [-0.14, -0.14, cam_z - 0.25],
        ]
    )
    line3(ax, box, color="#37474f", lw=1.2)
    top = box.copy()
    top[:, 2] = cam_z
    line3(ax, top, color="#37474f", lw=1.2)
    for i in range(4):
        line3(ax, np.stack([box[i], top[i]]), color="#37474f", lw=1.2)
    arrow3(ax, np.array([0, 0, cam_z + 0.02]), np.array([0, 0, cam_z + 0.45]), "#37474f", lw=1.2)
    text3(
        ax,
        np.array([0.0, 0.25, cam_z - 0.12]),
        "camera\n(looks up)",
        color="#37474f",
        fontsize=9,
        ha="left",
        va="center",
    )

    # Axes.
    L = 1.55
    for name, vec in (("x", [L, 0, 0]), ("y", [0, L, 0]), ("z", [0, 0, 1.25])):
        end = np.array(vec, float)
        arrow3(ax, np.zeros(3), end, AXIS_COLOR[name], lw=2.0, zorder=4)
        text3(
            ax,
            end * 1.08,
            name,
            color=AXIS_COLOR[name],
            fontsize=13,
            fontweight="bold",
            ha="center",
            va="center",
        )
    q0 = proj(np.zeros(3))
    ax.annotate(
        "$O_m$ (viewpoint)",
        (q0[0], q0[1]),
        (q0[0] - 0.95, q0[1] + 0.15),
        fontsize=11,
        ha="right",
        va="center",
        zorder=5,
        arrowprops={"arrowstyle": "-", "lw": 0.8, "color": "black"},
    )

    # Scene point, its foot on the horizontal plane, and the ray.
    foot = np.array([P[0], P[1], 0.0])
    line3(ax, np.stack([np.zeros(3), foot]), color="#455a64", lw=1.0, ls="--")
    line3(ax, np.stack([foot, P]), color="#455a64", lw=1.0, ls="--")
    line3(ax, np.stack([np.zeros(3), P]), color=POINT_COLOR, lw=1.6)
    qp = proj(P)
    ax.plot(*qp, "o", color=POINT_COLOR, ms=7, zorder=6)
    ax.text(qp[0] + 0.08, qp[1] - 0.05, "P = (x, y, z)", fontsize=11, ha="left", va="top")

    # theta: arc in the horizontal plane from +x to the foot direction, counter-clockwise.
    a = np.linspace(0, P_THETA, 60)
    arc = np.stack([0.75 * np.cos(a), 0.75 * np.sin(a), 0 * a], 1)
    line3(ax, arc[:-3], color=THETA_COLOR, lw=2.2)
    arrow3(ax, arc[-6], arc[-1], THETA_COLOR, lw=2.2)
    mid = arc[len(arc) // 2] * 1.12
    text3(ax, mid, r"$\theta$", color=THETA_COLOR, fontsize=15, ha="right", va="top")

    # rho: arc in the vertical plane of P, from the horizontal to the ray.
    b = np.linspace(0, P_RHO, 40)
    arc2 = np.stack(
        [1.5 * np.cos(b) * math.cos(P_THETA), 1.5 * np.cos(b) * math.sin(P_THETA), 1.5 * np.sin(b)],
        1,
    )
    line3(ax, arc2[:-3], color=RHO_COLOR, lw=2.2)
    arrow3(ax, arc2[-5], arc2[-1], RHO_COLOR, lw=2.2)
    text3(
        ax,
        arc2[len(arc2) // 2] + np.array([0.0, 0.12, 0.0]),
        r"$\rho$",
        color=RHO_COLOR,
        fontsize=15,
        ha="left",
        va="center",
    )

    ax.text(
        0.99,
        0.02,
        r"azimuth $\theta$ = atan2(y, x): 0 along +x, counter-clockwise seen from above"
        "\n"
        r"elevation $\rho$ = atan2(z, $\sqrt{x^2+y^2}$): 0 horizontal, + up"
        "\n"
        f"here: P = ({P[0]:g}, {P[1]:g}, {P[2]:g}),  "
        rf"$\theta$ = {math.degrees(P_THETA):.1f}°,  $\rho$ = {math.degrees(P_RHO):.1f}°",
        transform=ax.transAxes,
        ha="right",
        va="bottom",
        fontsize=9.5,
        multialignment="left",
        bbox={"boxstyle": "round", "fc": "white", "ec": "#b0bec5"},
    )
    ax.set_aspect("equal")
    ax.set_xlim(-2.45, 2.6)
    ax.set_ylim(-2.75, 1.45)
    ax.axis("off")


# --------------------------------------------------------------------------- (b) omni-image


def panel_omni_image(ax: Axes) -> None:
    ax.set_title("(b) omni-image: pixel (u, v), image angle $\\phi$, radius r", loc="left")
    W, H = 640, 480
    u0, v0 = 322.0, 236.0
    disc_r, cut_r = 215.0, 48.0
    ax.add_patch(Rectangle((-0.5, -0.5), W, H, fc="#263238", ec="black", lw=1.0))
    ax.add_patch(Circle((u0, v0), disc_r, fc="#cfd8dc", ec="#90a4ae", lw=1.0))
    ax.add_patch(Circle((u0, v0), cut_r, fc="#37474f", ec="#ffb300", lw=1.8, ls="--"))
    c135 = (u0 - cut_r * 0.707, v0 + cut_r * 0.707)
    arrow(ax, (c135[0] - 70, c135[1] + 70), c135, "#ffb300", lw=1.2, arrowstyle="->")
    ax.text(
        c135[0] - 72,
        c135[1] + 72,
        "cut-off circle\n(camera sees itself)",
        color="#5d4037",
        fontsize=9,
        ha="center",
        va="top",
        bbox={"fc": "#cfd8dc", "ec": "none", "pad": 1},
    )

    # image axes along the top-left corner
    arrow(ax, (-0.5, -0.5), (150, -0.5), AXIS_COLOR["x"], lw=2.2, clip_on=False)
    ax.text(152, -8, "u (column)", color=AXIS_COLOR["x"], fontsize=11, ha="left", va="bottom")
    arrow(ax, (-0.5, -0.5), (-0.5, 130), AXIS_COLOR["y"], lw=2.2, clip_on=False)
    ax.text(
        -10, 135, "v (row)", color=AXIS_COLOR["y"], fontsize=11, ha="right", va="top", rotation=90
    )
    ax.text(
        6,
        8,
        "(0, 0) = center of the\ntop-left pixel",
        color="white",
        fontsize=8.5,
        ha="left",
        va="top",
    )

    # center, reference direction, pixel p
    ax.plot(u0, v0, "+", color="#ffb300", ms=12, mew=2)
    ax.plot([u0, u0 - cut_r - 14], [v0, v0 - cut_r - 14], color="#ffb300", lw=0.8)
    ax.text(
        u0 - cut_r - 16,
        v0 - cut_r - 16,
        "image center $(u_0, v_0)$",
        color="#263238",
        fontsize=11,
        ha="right",
        va="bottom",
        bbox={"fc": "#cfd8dc", "ec": "none", "pad": 1},
    )
    ax.plot([u0, u0 + disc_r + 20], [v0, v0], color="#455a64", lw=1.0, ls=":")
    ax.text(
        u0 + disc_r + 24, v0, r"$\phi$ = 0 (+u)", fontsize=9, ha="left", va="center", color="white"
    )

    phi = math.radians(50.0)
    r = 150.0
    pu, pv = u0 + r * math.cos(phi), v0 + r * math.sin(phi)
    ax.plot([u0, pu], [v0, pv], color=POINT_COLOR, lw=1.6)
    ax.plot(pu, pv, "o", color=POINT_COLOR, ms=7)
    ax.text(
        pu + 10,
        pv + 4,
        "p = (u, v)",
        fontsize=11,
        ha="left",
        va="top",
        bbox={"fc": "#cfd8dc", "ec": "none", "pad": 1},
    )
    mr = 0.55 * r
    ax.text(
        u0 + mr * math.cos(phi) - 8,
        v0 + mr * math.sin(phi) + 8,
        "r",
        fontsize=13,
        ha="right",
        va="top",
        style="italic",
    )
    a = np.linspace(0, phi, 40)
    ax.plot(u0 + 80 * np.cos(a[:-3]), v0 + 80 * np.sin(a[:-3]), color=THETA_COLOR, lw=2.0)
    arrow(
        ax,
        (u0 + 80 * math.cos(a[-6]), v0 + 80 * math.sin(a[-6])),
        (u0 + 80 * math.cos(a[-1]), v0 + 80 * math.sin(a[-1])),
        THETA_COLOR,
        lw=2.0,
    )
    ax.text(
        u0 + 92 * math.cos(phi / 2),
        v0 + 92 * math.sin(phi / 2),
        r"$\phi$",
        color=THETA_COLOR,
        fontsize=15,
        ha="left",
        va="top",
    )

    ax.text(
        0.5,
        -0.03,
        r"$\phi$ = atan2(v − $v_0$, u − $u_0$)  (v points down: $\phi$ grows clockwise on screen)"
        "\n"
        r"r = hypot(u − $u_0$, v − $v_0$) = $f_r(\rho)$,   $\phi$ = s·$\theta$ + $\phi_0$,  s = ±1",
        transform=ax.transAxes,
        ha="center",
        va="top",
        fontsize=9.5,
    )
    ax.set_aspect("equal")
    ax.set_xlim(-70, W + 95)
    ax.set_ylim(H + 10, -45)  # v down
    ax.axis("off")


# --------------------------------------------------------------------------- (c) panorama


def panel_panorama(ax: Axes) -> None:
    W, H = 720, 180
    elev = (-60.0, 30.0)
    ax.set_title(
        f"(c) Panorama({W}, {H}, elevation_deg={elev}): columns clockwise seen from above, "
        "row 0 at the top",
        loc="left",
    )
    ax.add_patch(Rectangle((-0.5, -0.5), W, H, fc="#eceff1", ec="black", lw=1.0))
    # horizon row
    l_h = (elev[1] - 0.0) / (elev[1] - elev[0]) * H - 0.5
    ax.plot([-0.5, W - 0.5], [l_h, l_h], color="#90a4ae", lw=1.0, ls="--")
    ax.text(
        W - 4, l_h - 3, r"horizon $\rho$ = 0°", fontsize=9, ha="right", va="bottom", color="#546e7a"
    )

    # azimuth of column edges: theta = start - k * span / W (start 0, span 360)
    for k in range(0, W + 1, W // 8):
        az = (0.0 - k * 360.0 / W) % 360.0
        ax.plot([k - 0.5, k - 0.5], [H - 0.5, H + 6], color="black", lw=1.0)
        ax.text(k - 0.5, H + 9, f"{az:.0f}°", fontsize=9, ha="center", va="top")
    ax.text(-40, H + 9, r"$\theta$:", fontsize=11, ha="right", va="top", color=THETA_COLOR)
    for rho in (30, 0, -30, -60):
        l_edge = (elev[1] - rho) / (elev[1] - elev[0]) * H - 0.5
        ax.plot([-8, -0.5], [l_edge, l_edge], color="black", lw=1.0)
        ax.text(-11, l_edge, f"{rho}°", fontsize=9, ha="right", va="center")
    ax.text(-40, -14, r"$\rho$:", fontsize=11, ha="right", va="bottom", color=RHO_COLOR)

    # column / row direction arrows
    arrow(ax, (10, -22), (230, -22), THETA_COLOR, lw=2.2, clip_on=False)
    ax.text(
        240,
        -22,
        r"column k: $\theta$ decreases (clockwise seen from above)",
        color=THETA_COLOR,
        fontsize=10,
        ha="left",
        va="center",
    )
    arrow(ax, (W + 22, 0), (W + 22, 120), RHO_COLOR, lw=2.2, clip_on=False)
    ax.text(
        W + 30,
        4,
        "row l:\n" r"$\rho$ decreases" "\n(row 0 = top\n= highest)",
        color=RHO_COLOR,
        fontsize=10,
        ha="left",
        va="top",
    )

    # where P of panel (a) lands (fractional column/row, pixel-center convention)
    theta_deg, rho_deg = math.degrees(P_THETA), math.degrees(P_RHO)
    kcol = ((0.0 - theta_deg) % 360.0) / (360.0 / W) - 0.5
    lrow = (elev[1] - rho_deg) / ((elev[1] - elev[0]) / H) - 0.5
    ax.plot(kcol, lrow, "o", color=POINT_COLOR, ms=7)
    ax.text(
        kcol + 8,
        lrow - 6,
        f"P: column {kcol:.1f}, row {lrow:.1f}",
        fontsize=9.5,
        ha="left",
        va="bottom",
    )

    ax.text(
        -75,
        H + 38,
        r"pixel (k, l) samples its cell center:  $\theta_k$ = start − (k + ½)·span/W,   "
        r"$\rho_l$ = top − (l + ½)·(top − bottom)/H.   "
        "\n"
        r"ccw=1 (clockwise=False) makes $\theta$ grow with k, as in the dissertation's eq. 4.9 "
        "(the view is then mirror-imaged).",
        ha="left",
        va="top",
        fontsize=9.5,
    )
    ax.set_aspect("equal")
    ax.set_xlim(-75, W + 250)
    ax.set_ylim(H + 78, -40)
    ax.axis("off")

    # small top-view compass: x right, y up, columns sweep clockwise
    ins = ax.inset_axes((W + 125, -20, 125, 200), transform=ax.transData)
    t = np.linspace(0, 2 * math.pi, 100)
    ins.plot(np.cos(t), np.sin(t), color="#90a4ae", lw=1.0)
    arrow(ins, (0, 0), (1.25, 0), AXIS_COLOR["x"], lw=1.6)
    arrow(ins, (0, 0), (0, 1.25), AXIS_COLOR["y"], lw=1.6)
    ins.text(1.32, 0, "x", color=AXIS_COLOR["x"], fontsize=10, va="center", fontweight="bold")
    ins.text(0, 1.33, "y", color=AXIS_COLOR["y"], fontsize=10, ha="center", fontweight="bold")
    a = np.linspace(math.radians(-20), math.radians(-150), 40)
    ins.plot(0.72 * np.cos(a[:-3]), 0.72 * np.sin(a[:-3]), color=THETA_COLOR, lw=1.8)
    arrow(
        ins,
        (0.72 * math.cos(a[-5]), 0.72 * math.sin(a[-5])),
        (0.72 * math.cos(a[-1]), 0.72 * math.sin(a[-1])),
        THETA_COLOR,
        lw=1.8,
    )
    ins.text(0, -1.25, "seen from above:\ncolumns go clockwise", fontsize=8, ha="center", va="top")
    ins.set_aspect("equal")
    ins.set_xlim(-1.4, 1.6)
    ins.set_ylim(-1.9, 1.6)
    ins.axis("off")


# --------------------------------------------------------------------------- (d) pixel centers


def panel_pixels(ax: Axes) -> None:
    ax.set_title("(d) pixel centers", loc="left")
    n = 3
    for i in range(n):
        for j in range(n):
            ax.add_patch(
                Rectangle(
                    (i - 0.5, j - 0.5),
                    1,
                    1,
                    fc="#eceff1" if (i + j) % 2 else "#cfd8dc",
                    ec="#78909c",
                    lw=1.0,
                )
            )
            ax.plot(i, j, "o", color="black", ms=4)
    ax.text(0.06, 0.08, "(0, 0)", fontsize=10, ha="left", va="top")
    ax.text(1.06, 0.08, "(1, 0)", fontsize=10, ha="left", va="top")
    ax.text(0.06, 1.08, "(0, 1)", fontsize=10, ha="left", va="top")
    arrow(ax, (-0.5, -0.5), (2.9, -0.5), AXIS_COLOR["x"], lw=2.0, clip_on=False)
    ax.text(2.95, -0.5, "u", color=AXIS_COLOR["x"], fontsize=12, va="center", fontweight="bold")
    arrow(ax, (-0.5, -0.5), (-0.5, 2.9), AXIS_COLOR["y"], lw=2.0, clip_on=False)
    ax.text(
        -0.5, 3.0, "v", color=AXIS_COLOR["y"], fontsize=12, ha="center", va="top", fontweight="bold"
    )
    ax.text(-0.55, -0.58, "(−0.5, −0.5)", fontsize=8.5, ha="left", va="bottom", color="#455a64")
    ax.text(
        1.0,
        3.45,
        "a W×H image covers\nu ∈ [−0.5, W − 0.5],\nv ∈ [−0.5, H − 0.5];\n"
        "its geometric center is\n((W − 1)/2, (H − 1)/2)",
        fontsize=8.5,
        ha="center",
        va="top",
    )
    ax.set_aspect("equal")
    ax.set_xlim(-0.9, 3.3)
    ax.set_ylim(5.0, -1.0)
    ax.axis("off")


def main() -> None:
    plt.rcParams.update({"font.size": 10, "axes.titlesize": 11, "axes.titleweight": "bold"})
    fig = plt.figure(figsize=(13.0, 9.6), dpi=100)
    gs = fig.add_gridspec(
        2,
        3,
        height_ratios=(1.55, 1.0),
        width_ratios=(1.0, 1.0, 0.42),
        hspace=0.18,
        wspace=0.06,
        left=0.02,
        right=0.99,
        top=0.96,
        bottom=0.02,
    )
    panel_camera_frame(fig.add_subplot(gs[0, 0]))
    panel_omni_image(fig.add_subplot(gs[0, 1:]))
    panel_panorama(fig.add_subplot(gs[1, :2]))
    panel_pixels(fig.add_subplot(gs[1, 2]))
    fig.savefig(OUT, dpi=100)
    plt.close(fig)
    print(f"wrote {OUT} ({OUT.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
