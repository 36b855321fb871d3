"""Mei (cv2.omnidir) calibration: is fx recoverable? The table of docs/fisheye-calibration.md.

Run: ``.venv/bin/python scripts/mei_identifiability.py`` (about 3 minutes on 2 cores);
``... --xi``: only the Cramer-Rao bound of fx for other xi (a few seconds).

For each rendered sequence design (truth: the Mei test lens of omnidev.sim.chessboard, or the
same lens without distortion) and solver setting, 0.2 px Gaussian noise is added to the exact
corners (seed 5) and ``calibrate_views`` runs with 4-fold held-out evaluation. Printed per row:
fx error (reported 1 sigma), xi error (reported 1 sigma), fx / (1 + xi) error (reported
1 sigma), held-out and training RMS, and the Cramer-Rao bound of fx and xi at the truth
(``intrinsic_covariance`` with the true lens, poses and corners, sigma 0.2 px).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from omnidev.fisheye import calibrate as cal
from omnidev.fisheye.models import Unified
from omnidev.fisheye.pattern import parse_pattern
from omnidev.sim.chessboard import default_lens, default_pose_options, render_sequence

SIZE = (800, 800)
BOARD = parse_pattern("chessboard:9x6,30")
NOISE = 0.2
_LENS = default_lens("mei", SIZE)
assert isinstance(_LENS, Unified)
MEI: Unified = _LENS
MEI0 = dataclasses.replace(MEI, k1=0.0, k2=0.0, p1=0.0, p2=0.0)
MEI_OPTS = default_pose_options("mei")
WIDE = {"max_angle_deg": 100.0, "board_angle_deg": (25.0, 60.0)}
DESIGNS = {  # code: (description, truth, views, pose options)
    "A": ("14 views, KB4 pose options (<= 80 deg, boards 55-95 deg)", MEI, 14, {}),
    "B": ("24 views, Mei pose options (<= 100 deg, boards 30-95 deg)", MEI, 24, MEI_OPTS),
    "C": ("40 views, Mei pose options", MEI, 40, MEI_OPTS),
    "D": ("40 views, <= 100 deg, boards 25-60 deg", MEI, 40, WIDE),
    "B0": ("as B, truth without distortion (k1 = k2 = p1 = p2 = 0)", MEI0, 24, MEI_OPTS),
}
PS = ("p1", "p2")
KP = ("k1", "k2", "p1", "p2")
VARIANTS = {  # name: (fix, iterations, design codes)
    "all free (default)": ((), 300, ("A", "B", "C", "D", "B0")),
    "p1 p2 held at 0": (PS, 300, ("A", "B", "C", "D", "B0")),
    "all free, 3000 iterations, eps 1e-16": ((), 3000, ("A", "B")),
    "k1 k2 p1 p2 held at 0": (KP, 300, ("B", "B0")),
}


def main() -> None:
    print(
        "| design | solver | fx error (1 sigma) | xi error (1 sigma) | fx/(1+xi) error (1 sigma) "
        "| held-out / train RMS px | bound at truth: fx, xi | time |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for code, (dname, truth, n, opts) in DESIGNS.items():
        seq = render_sequence(truth, SIZE, BOARD, n, seed=1, images=False, **opts)  # type: ignore[arg-type]
        obj = [BOARD.object_points()] * n
        uv_true = [v.corners_uv for v in seq.views]
        rv = [v.rvec for v in seq.views]
        tv = [v.translation for v in seq.views]
        dets = [
            cal.Detection(f"view{i:02d}", c, BOARD.object_points())
            for i, c in enumerate(seq.noisy_corners(NOISE, seed=5))
        ]
        for vname, (fix, iters, which) in VARIANTS.items():
            if code not in which:
                continue
            cal.CRITERIA = (3, iters, 1e-12 if iters == 300 else 1e-16)
            crb = cal.intrinsic_covariance(
                "mei", truth, obj, uv_true, rv, tv, fixed=fix, sigma_px=NOISE
            )
            t0 = time.perf_counter()
            res = cal.calibrate_views(dets, SIZE, "mei", fix=fix)
            dt = time.perf_counter() - t0
            p = cal.params_of(res.camera.lens)
            sd = np.array([res.std[k] for k in cal.PARAMS["mei"]])
            cov = res.correlation * np.outer(sd, sd)
            g = np.zeros(9)
            g[0], g[4] = 1 / (1 + p[4]), -p[0] / (1 + p[4]) ** 2
            fe, ft = p[0] / (1 + p[4]), truth.fx / (1 + truth.xi)
            print(
                f"| {code} | {vname} | {100 * (p[0] / truth.fx - 1):+.2f} % "
                f"({100 * sd[0] / p[0]:.3g} %) | {p[4] - truth.xi:+.3f} ({sd[4]:.3g}) | "
                f"{100 * (fe / ft - 1):+.3f} % ({100 * math.sqrt(g @ cov @ g) / fe:.3f} %) | "
                f"{res.heldout_rms_px:.3f} / {res.train_rms_px:.3f} | "
                f"{100 * math.sqrt(crb[0, 0]) / truth.fx:.3g} %, {math.sqrt(crb[4, 4]):.3g} | "
                f"{dt:.0f} s |",
                flush=True,
            )
        uv = np.concatenate(uv_true)
        r = np.hypot(uv[:, 0] - truth.cx, uv[:, 1] - truth.cy)
        inner = min(
            truth.cx + 0.5, SIZE[0] - 0.5 - truth.cx, truth.cy + 0.5, SIZE[1] - 0.5 - truth.cy
        )
        ang = np.degrees(np.arccos(np.clip(truth.unproject(uv)[0][:, 2], -1, 1)))
        print(f"| {code} | {dname}: corners reach {r.max() / inner:.2f} of the inscribed radius, "
              f"up to {ang.max():.1f} deg off the axis |||||||")  # fmt: skip


def xi_bounds() -> None:
    """The bound on fx at the truth for Mei lenses of other xi, fx / (1 + xi) kept."""
    f_axis = MEI.fx / (1 + MEI.xi)
    for xi in (0.5, 0.8, 0.95, 1.0, 1.2, 1.5, 2.0):
        lens = dataclasses.replace(
            MEI, fx=f_axis * (1 + xi), fy=f_axis * (1 + xi) * MEI.fy / MEI.fx, xi=xi
        )
        seq = render_sequence(lens, SIZE, BOARD, 24, seed=1, images=False, **MEI_OPTS)
        args = (
            [BOARD.object_points()] * 24,
            [v.corners_uv for v in seq.views],
            [v.rvec for v in seq.views],
            [v.translation for v in seq.views],
        )
        out = []
        for fix in ((), PS, ("k2",), ("k1", "k2")):
            cov = cal.intrinsic_covariance("mei", lens, *args, fixed=fix, sigma_px=NOISE)
            out.append(
                f"{' '.join(fix) or 'none'} held: {100 * math.sqrt(cov[0, 0]) / lens.fx:.3g} %"
            )
        print(f"xi {xi}: 1 sigma of fx " + ", ".join(out), flush=True)


if __name__ == "__main__":
    import sys

    xi_bounds() if sys.argv[1:] == ["--xi"] else main()
