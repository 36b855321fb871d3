"""Command-line option parsing shared by the subcommands: KEY=VALUE items, sizes, numbers."""

from __future__ import annotations

import math
from typing import Any

from omnidev.errors import CalibrationError, OmnidevError


def key_values(items: list[str], flag: str) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; a malformed item names ``flag``."""
    out: dict[str, str] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise OmnidevError(f"{flag} must be KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


def typed_value(text: str) -> Any:
    """An option value as TOML would give it: int, float, true/false, else the string."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def sink_options(items: list[str]) -> dict[str, Any]:
    """Typed sink options from repeated ``--sink-option KEY=VALUE``."""
    return {k: typed_value(v) for k, v in key_values(items, "--sink-option").items()}


MAX_SIDE = 65500
"""Largest image side in pixels (OpenCV's codecs stop near 65535)."""


def parse_size(
    text: str, what: str = "--size", minimum: int = 1, maximum: int = MAX_SIDE
) -> tuple[int, int]:
    """``"640x480"`` -> ``(640, 480)`` (pixels); an error names ``what`` and the range."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise OmnidevError(f"{what} {text!r} is not WxH in pixels (e.g. 640x480)") from None
    if w < minimum or h < minimum:
        raise OmnidevError(f"{what} {text!r}: at least {minimum}x{minimum}")
    if w > maximum or h > maximum:
        raise OmnidevError(f"{what} {text!r}: at most {maximum} pixels per side")
    return w, h


def parse_floats(text: str, n: int, what: str) -> tuple[float, ...]:
    """Parse ``"a,b[,c]"`` into n finite floats; error names ``what``."""
    parts = [p.strip() for p in text.split(",")]
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        raise CalibrationError(
            f"{what} must be {n} comma-separated numbers, got {text!r}"
        ) from None
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise CalibrationError(f"{what} must be {n} comma-separated finite numbers, got {text!r}")
    return vals
