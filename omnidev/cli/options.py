"""``KEY=VALUE`` command-line options shared by the subcommands."""

from __future__ import annotations

from typing import Any

from omnidev.errors import OmnidevError


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
