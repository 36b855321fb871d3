"""Landmark files: CSV with header ``u,v,X,Y,Z`` (image pixels; world coordinates, one unit).

An optional ``group`` column (an integer, e.g. the board a corner is on, as
``omnidev landmarks board`` writes) lets the generalized fit leave out whole
groups when it cross-validates.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from omnidev.errors import CalibrationError
from omnidev.inputfile import read_text

COLUMNS = ("u", "v", "X", "Y", "Z")


@dataclass(frozen=True)
class Landmarks:
    """Landmark pairs: (n, 2) pixels ``uv``, (n, 3) world points ``xyz``, CSV ``rows``."""

    uv: NDArray[np.float64]
    xyz: NDArray[np.float64]
    rows: tuple[int, ...]
    groups: NDArray[np.intp] | None = None


MAX_VALUE = 1e9
"""Largest |value| of a landmark coordinate (pixels or world units)."""


def read_landmarks_csv(path: Path) -> Landmarks:
    """Read a landmark CSV; every error names the file and the line (and column)."""
    path = Path(path)
    text = read_text(path, "landmark file", error=CalibrationError)
    try:
        lines = list(csv.reader(text.splitlines()))
    except csv.Error as exc:
        raise CalibrationError(f"{path}: not a CSV file ({exc})") from None
    reader = iter(lines)
    header = next(reader, None)
    if header is None:
        raise CalibrationError(f"{path}: empty file; expected a header line u,v,X,Y,Z")
    names = [h.strip() for h in header]
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        raise CalibrationError(
            f"{path} line 1: header lacks column(s) {', '.join(missing)} "
            f"(expected u,v,X,Y,Z, got {','.join(names)})"
        )
    idx = [names.index(c) for c in COLUMNS]
    gi = names.index("group") if "group" in names else None
    values: list[list[float]] = []
    rows: list[int] = []
    groups: list[int] = []
    for lineno, fields in enumerate(reader, start=2):
        if not fields or all(not f.strip() for f in fields) or fields[0].lstrip().startswith("#"):
            continue
        if len(fields) != len(names):
            raise CalibrationError(
                f"{path} line {lineno}: {len(fields)} fields, the header has {len(names)}"
            )
        row: list[float] = []
        for col, i in zip(COLUMNS, idx, strict=True):
            raw = fields[i].strip()
            try:
                x = float(raw)
            except ValueError:
                raise CalibrationError(
                    f"{path} line {lineno}: column {col} is {raw!r}, not a number"
                ) from None
            if not math.isfinite(x):
                raise CalibrationError(f"{path} line {lineno}: column {col} is not finite ({raw})")
            if abs(x) > MAX_VALUE:
                raise CalibrationError(
                    f"{path} line {lineno}: column {col} is {raw}; |value| must be <= {MAX_VALUE:g}"
                )
            row.append(x)
        if gi is not None:
            raw = fields[gi].strip()
            try:
                group = int(raw)
            except ValueError:
                raise CalibrationError(
                    f"{path} line {lineno}: column group is {raw!r}, not an integer"
                ) from None
            if abs(group) > MAX_VALUE:
                raise CalibrationError(
                    f"{path} line {lineno}: column group is {raw}; |group| must be <= {MAX_VALUE:g}"
                )
            groups.append(group)
        values.append(row)
        rows.append(lineno)
    if not values:
        raise CalibrationError(f"{path}: no landmark rows after the header")
    arr = np.array(values, np.float64)
    g = np.array(groups, np.intp) if gi is not None else None
    return Landmarks(arr[:, :2], arr[:, 2:], tuple(rows), g)


def check_inside_image(lm: Landmarks, size: tuple[int, int], path: Path | str) -> None:
    """Refuse a landmark whose image point (u, v) lies outside a ``size`` (W, H) image
    (pixel centres at whole numbers: the image spans -0.5 .. W - 0.5), naming its line."""
    w, h = size
    u, v = lm.uv[:, 0], lm.uv[:, 1]
    out = np.flatnonzero((u < -0.5) | (u > w - 0.5) | (v < -0.5) | (v > h - 0.5))
    if out.size:
        k = int(out[0])
        more = f" (and {out.size - 1} more)" if out.size > 1 else ""
        raise CalibrationError(
            f"{path} line {lm.rows[k]}: landmark (u, v) = ({u[k]:g}, {v[k]:g}) lies outside "
            f"the {w}x{h} image{more}"
        )
