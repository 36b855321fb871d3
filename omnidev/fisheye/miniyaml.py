"""A small YAML reader for calibration files (Kalibr camchains and similar), without PyYAML.

omnidev does not depend on PyYAML, and ``cv2.FileStorage`` rejects the block style
PyYAML writes (a sequence's ``-`` at its key's indentation, as in every Kalibr
``T_cn_cnm1``). This reads the subset such files use:

- block mappings (``key: value``, ``key:`` + an indented block) and block sequences
  (``- value``, also at the parent key's indentation);
- flow sequences and mappings (``[1, 2]``, ``{fx: 1, fy: 2}``), which may span lines;
- scalars: integers, floats (``.inf``, ``.nan`` too), ``true``/``false``, ``null``/``~``,
  plain and quoted strings; ``#`` comments; ``%`` directives and ``---``/``...`` markers.

Anchors, aliases, tags, multi-line scalars and multiple documents are not read: they
raise :class:`YamlError` with the line number.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any


class YamlError(ValueError):
    """Text outside the subset; the message starts with ``line N:``."""


_INT = re.compile(r"^[-+]?(0|[1-9][0-9_]*)$")
_FLOAT = re.compile(r"^[-+]?(\.[0-9]+|[0-9][0-9_]*(\.[0-9_]*)?)([eE][-+]?[0-9]+)?$")
_SPECIAL = {
    ".inf": float("inf"),
    "+.inf": float("inf"),
    "-.inf": float("-inf"),
    ".nan": float("nan"),
    "true": True,
    "false": False,
    "null": None,
    "~": None,
    "": None,
}


def scalar(text: str, line: int) -> Any:
    """A plain or quoted scalar's value."""
    t = text.strip()
    if len(t) >= 2 and t[0] == t[-1] and t[0] in "'\"":
        body = t[1:-1]
        return body.replace("''", "'") if t[0] == "'" else body.replace('\\"', '"')
    if t[:1] in ("&", "*", "!", "|", ">"):
        raise YamlError(f"line {line}: anchors, aliases, tags and block scalars are not read")
    low = t.lower()
    if low in _SPECIAL:
        return _SPECIAL[low]
    if _INT.match(t):
        return int(t.replace("_", ""))
    if _FLOAT.match(t):
        return float(t.replace("_", ""))
    return t


def _strip_comment(text: str) -> str:
    """``text`` without a trailing ``# comment`` (a ``#`` inside quotes is kept)."""
    quote = ""
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1] in " \t"):
            return text[:i]
    return text


def _depth(text: str) -> int:
    """Open brackets minus closed ones outside quotes."""
    depth, quote = 0, ""
    for ch in text:
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
    return depth


def _logical_lines(text: str) -> list[tuple[int, int, str]]:
    """(line number, indentation, content) with comments removed and flow text joined."""
    out: list[tuple[int, int, str]] = []
    pending: tuple[int, int, str] | None = None
    for n, raw in enumerate(text.splitlines(), start=1):
        if "\t" in raw[: len(raw) - len(raw.lstrip())]:
            raise YamlError(f"line {n}: tab in indentation")
        body = _strip_comment(raw).rstrip()
        if pending is not None:
            pn, pi, pt = pending
            joined = pt + " " + body.strip()
            if _depth(joined) > 0:
                pending = (pn, pi, joined)
            else:
                out.append((pn, pi, joined))
                pending = None
            continue
        stripped = body.strip()
        if not stripped or stripped.startswith("%") or stripped in ("---", "..."):
            if stripped == "---" and out:
                raise YamlError(f"line {n}: a second document")
            continue
        item = (n, len(body) - len(body.lstrip()), stripped)
        if _depth(stripped) > 0:
            pending = item
        else:
            out.append(item)
    if pending is not None:
        raise YamlError(f"line {pending[0]}: unclosed bracket")
    return out


def _top_level(text: str) -> Iterator[int]:
    """Indices of the characters of ``text`` outside quotes and brackets."""
    quote = ""
    depth = 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif depth == 0:
            yield i


def _split_flow(body: str, line: int) -> list[str]:
    """Split the inside of a flow collection at top-level commas."""
    parts, start = [], 0
    for i in _top_level(body):
        if body[i] == ",":
            parts.append(body[start:i])
            start = i + 1
    parts.append(body[start:])
    parts = [p.strip() for p in parts]
    if parts and parts[-1] == "":
        parts.pop()  # a trailing comma
    if any(p == "" for p in parts):
        raise YamlError(f"line {line}: empty item in a flow collection")
    return parts


def _key_split(text: str) -> tuple[str, str] | None:
    """``key: rest`` -> (key, rest); None if ``text`` is not a mapping entry."""
    for i in _top_level(text):
        if text[i] == ":" and (i + 1 == len(text) or text[i + 1] == " "):
            return text[:i].strip(), text[i + 1 :].strip()
    return None


def flow(text: str, line: int) -> Any:
    """A flow value: ``[...]``, ``{...}`` or a scalar."""
    t = text.strip()
    if t.startswith("["):
        if not t.endswith("]"):
            raise YamlError(f"line {line}: text after a flow sequence")
        return [flow(p, line) for p in _split_flow(t[1:-1], line)]
    if t.startswith("{"):
        if not t.endswith("}"):
            raise YamlError(f"line {line}: text after a flow mapping")
        out: dict[str, Any] = {}
        for p in _split_flow(t[1:-1], line):
            kv = _key_split(p)
            if kv is None:
                raise YamlError(f"line {line}: {p!r} in a flow mapping is not 'key: value'")
            out[str(scalar(kv[0], line))] = flow(kv[1], line)
        return out
    return scalar(t, line)


def _block(lines: list[tuple[int, int, str]], i: int, indent: int) -> tuple[Any, int]:
    """Parse the block starting at ``lines[i]`` (indentation ``indent``); (value, next i)."""
    n, _, text = lines[i]
    if text == "-" or text.startswith("- "):
        seq: list[Any] = []
        while (
            i < len(lines)
            and lines[i][1] == indent
            and (lines[i][2] == "-" or lines[i][2].startswith("- "))
        ):
            n, _, text = lines[i]
            rest = text[1:].strip()
            i += 1
            if rest:
                if _key_split(rest) is not None and not rest.startswith(("[", "{")):
                    raise YamlError(f"line {n}: mappings inside block sequences are not read")
                seq.append(flow(rest, n))
            elif i < len(lines) and lines[i][1] > indent:
                value, i = _block(lines, i, lines[i][1])
                seq.append(value)
            else:
                seq.append(None)
        return seq, i
    mapping: dict[str, Any] = {}
    while i < len(lines) and lines[i][1] == indent:
        n, _, text = lines[i]
        kv = _key_split(text)
        if kv is None:
            raise YamlError(f"line {n}: expected 'key: value', got {text!r}")
        key, rest = str(scalar(kv[0], n)), kv[1]
        if key in mapping:
            raise YamlError(f"line {n}: key {key!r} given twice")
        i += 1
        if rest:
            mapping[key] = flow(rest, n)
        elif i < len(lines) and (
            lines[i][1] > indent
            or (lines[i][1] == indent and (lines[i][2] == "-" or lines[i][2].startswith("- ")))
        ):
            mapping[key], i = _block(lines, i, lines[i][1])
        else:
            mapping[key] = None
    if i < len(lines) and lines[i][1] > indent:
        raise YamlError(f"line {lines[i][0]}: unexpected indentation")
    return mapping, i


def loads(text: str) -> Any:
    r"""The value of a YAML document in the subset above (a dict for calibration files).

    >>> loads("cam0:\n  T_cn_cnm1:\n  - [1, 0]\n  - [0, 1]\n  intrinsics: [190.9, 2e2]  # fu fv\n")
    {'cam0': {'T_cn_cnm1': [[1, 0], [0, 1]], 'intrinsics': [190.9, 200.0]}}
    """
    lines = _logical_lines(text)
    if not lines:
        return None
    if len(lines) == 1 and lines[0][2].startswith(("[", "{")):
        return flow(lines[0][2], lines[0][0])
    value, i = _block(lines, 0, lines[0][1])
    if i < len(lines):
        raise YamlError(f"line {lines[i][0]}: indentation does not match the lines above")
    return value
