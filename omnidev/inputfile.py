"""Reading the files a user names: size limits, and one-line errors for what is not a file.

Every reader of a user's text file (rig files, daemon configurations, landmark
CSVs, layouts, point files, recordings, other tools' calibrations) goes
through :func:`read_text` or :func:`read_bytes`, so that each of them says the
same thing, naming the file, for a folder, a symlink loop, a device such as
/dev/zero, an unreadable file, a file far too large to be what it claims, or
bytes that are not UTF-8 text; and none of them reads without end
(:func:`not_a_file` says the same, before any reading, of a file another library opens
later: a calibration cv2 reads, a recording, a landmark layout). The
TOML and JSON parsers here also refuse absurd nesting and absurd numbers
(:func:`check_magnitudes`), naming the key.

The errors are of the class the caller passes (``error=ConfigError`` for a
daemon configuration, ...), so the CLI prints them as one line.

>>> import tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "x.toml"
>>> _ = p.write_bytes(b"name = 'caf\\xe9'\\n")
>>> try:
...     read_text(p, "rig file")
... except OmnidevError as exc:
...     print(str(exc).split(": ", 1)[1])
cannot read the rig file: line 1, column 12 is not UTF-8 text (byte 0xe9); save it as UTF-8
"""

from __future__ import annotations

import errno
import gzip
import io
import json
import math
import os
import stat
import tomllib
import zlib
from pathlib import Path
from typing import Any

from omnidev.errors import OmnidevError

MAX_TEXT_BYTES = 64 << 20
"""Largest text input file read (64 MiB): far above any real rig, config, CSV or calibration."""

MAX_NESTING = 64
"""Deepest nesting of lists/tables accepted in a JSON or TOML document."""

MAX_MAGNITUDE = 1e15
"""Largest |float| accepted in any file the project reads (TOML, JSON, calibration YAML).

No length in mm or px, angle, rate or coefficient comes near it; 1e308 and its like
pass ``isfinite`` and then overflow to inf in the first square or polynomial downstream,
so they are refused where the file is read, naming the key."""

MAX_INTEGER = (1 << 63) - 1
"""Largest |integer| accepted in a TOML or JSON file (what fits a 64-bit signed integer;
nanosecond timestamps fit, a 30-digit count does not)."""


def _describe_size(n: int) -> str:
    return f"{n / (1 << 20):.0f} MiB" if n >= 1 << 20 else f"{n} bytes"


def not_a_file(path: Path | str, what: str) -> str | None:
    """Why ``path`` cannot be read as a ``what`` (a file another reader opens later), in
    the words of :func:`read_bytes`: "<what> not found", "is a folder, not a <what>", "is
    a device, not a regular file; ..."; None for a regular file (symlinks followed)."""
    try:
        st = os.stat(path)
    except OSError as exc:
        return _open_reason(Path(path), what, exc)
    return _kind_problem(st.st_mode, what)


def _kind_problem(mode: int, what: str) -> str | None:
    """Why a file of mode ``mode`` is not a regular file to read as a ``what``, or None."""
    if stat.S_ISDIR(mode):
        return f"is a folder, not a {what}"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        kind = "a device"
    elif stat.S_ISFIFO(mode):
        kind = "a FIFO"
    else:
        kind = "a special file"
    return f"is {kind}, not a regular file; give the {what} as a file"


def _open_reason(path: Path, what: str, exc: OSError) -> str:
    """Why opening ``path`` (a ``what``) failed with ``exc``, without the path."""
    if exc.errno == errno.ENOENT:
        if os.path.islink(path):
            return f"{what} not found (a symlink to {os.readlink(path)!r}, absent)"
        return f"{what} not found"
    if exc.errno == errno.ELOOP:
        return f"{what} is a symlink loop"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return f"permission denied reading the {what}"
    if exc.errno == errno.EISDIR:
        return f"is a folder, not a {what}"
    return f"cannot read the {what}: {exc.strerror or exc}"


def _open_error(path: Path, what: str, exc: OSError, error: type[OmnidevError]) -> OmnidevError:
    return error(f"{path}: {_open_reason(path, what, exc)}")


def read_bytes(
    path: Path | str,
    what: str,
    *,
    error: type[OmnidevError] = OmnidevError,
    limit: int = MAX_TEXT_BYTES,
) -> bytes:
    """The bytes of ``path``, at most ``limit``; an :class:`OmnidevError` of class ``error``
    (naming the file and ``what`` it should be) for a folder, a symlink loop, a device,
    a FIFO, a missing or unreadable file, or more than ``limit`` bytes."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise _open_error(path, what, exc, error) from None
    try:
        st = os.fstat(fd)
        why = _kind_problem(st.st_mode, what)
        if why is not None:
            raise error(f"{path}: {why}")
        if st.st_size > limit:
            raise error(
                f"{path}: {_describe_size(st.st_size)}, larger than any {what} "
                f"(limit {_describe_size(limit)})"
            )
        chunks = []
        total = 0
        while True:
            try:
                chunk = os.read(fd, 1 << 20)
            except OSError as exc:
                raise _open_error(path, what, exc, error) from None
            if not chunk:
                break
            total += len(chunk)
            if total > limit:  # a file that grows while it is read
                raise error(f"{path}: larger than any {what} (limit {_describe_size(limit)})")
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def decode_utf8(data: bytes, path: Path | str, what: str, error: type[OmnidevError]) -> str:
    """``data`` as UTF-8 (a leading byte-order mark dropped); the error names line and column."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        start = 3 if data.startswith(b"\xef\xbb\xbf") else 0
        before = data[start : exc.start]
        line = before.count(b"\n") + 1
        column = exc.start - (before.rfind(b"\n") + 1 + start) + 1
        raise error(
            f"{path}: cannot read the {what}: line {line}, column {column} is not UTF-8 text "
            f"(byte 0x{data[exc.start]:02x}); save it as UTF-8"
        ) from None


def read_text(
    path: Path | str,
    what: str,
    *,
    error: type[OmnidevError] = OmnidevError,
    limit: int = MAX_TEXT_BYTES,
) -> str:
    """The UTF-8 text of ``path`` (see :func:`read_bytes`); NUL bytes are refused too."""
    data = read_bytes(path, what, error=error, limit=limit)
    text = decode_utf8(data, path, what, error)
    nul = text.find("\0")
    if nul >= 0:
        line = text.count("\n", 0, nul) + 1
        raise error(f"{path}: line {line}: a NUL byte; this is not a {what} (a binary file?)")
    return text


def _depth(text: str, opens: str, closes: str) -> int:
    """Deepest bracket nesting of ``text``, ignoring quoted strings roughly (an upper bound)."""
    depth = deepest = 0
    for ch in text:
        if ch in opens:
            depth += 1
            deepest = max(deepest, depth)
        elif ch in closes:
            depth -= 1
    return deepest


def check_nesting(text: str, path: Path | str, what: str, error: type[OmnidevError]) -> None:
    """Refuse a document nested deeper than :data:`MAX_NESTING` (parsers recurse per level)."""
    if _depth(text, "[{", "]}") > MAX_NESTING:
        raise error(f"{path}: nested deeper than {MAX_NESTING} levels; not a {what}")


def _key_path(where: str, key: object) -> str:
    if isinstance(key, int):
        return f"{where}[{key}]"
    return f"{where}.{key}" if where else str(key)


def check_magnitudes(
    doc: Any, path: Path | str, what: str, error: type[OmnidevError] = OmnidevError
) -> None:
    """Refuse a float beyond :data:`MAX_MAGNITUDE` or an integer beyond :data:`MAX_INTEGER`
    anywhere in a parsed document, naming its key path (``a.b[2]``). NaN and inf are left
    to the reader of each key, which knows whether it takes them."""
    stack: list[tuple[str, Any]] = [("", doc)]
    while stack:
        where, node = stack.pop()
        if isinstance(node, dict):
            stack.extend((_key_path(where, k), v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((_key_path(where, i), v) for i, v in enumerate(node))
        elif isinstance(node, bool):
            continue
        elif isinstance(node, int) and abs(node) > MAX_INTEGER:
            raise error(
                f"{path}: {where or 'the document'} is {node}, an integer beyond 64 bits; "
                f"not a valid {what}"
            )
        elif isinstance(node, float) and node == node and MAX_MAGNITUDE < abs(node) < math.inf:
            raise error(
                f"{path}: {where or 'the document'} is {node:g}; numbers in a {what} must "
                f"be within +-{MAX_MAGNITUDE:g}"
            )


def loads_toml(
    text: str, path: Path | str, what: str, error: type[OmnidevError] = OmnidevError
) -> dict[str, Any]:
    """Parse TOML text; a syntax error, absurd nesting or an absurd number
    (:func:`check_magnitudes`) is one line naming the file."""
    check_nesting(text, path, what, error)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML ({exc})") from None
    except ValueError:  # an integer of more than 4300 digits (sys.get_int_max_str_digits)
        raise error(f"{path}: an integer with thousands of digits; not a {what}") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply; not a {what}") from None
    check_magnitudes(doc, path, what, error)
    return doc


def read_toml(
    path: Path | str, what: str, *, error: type[OmnidevError] = OmnidevError
) -> dict[str, Any]:
    """:func:`read_text` then :func:`loads_toml`."""
    return loads_toml(read_text(path, what, error=error), path, what, error)


def loads_json(
    text: str, path: Path | str, what: str, error: type[OmnidevError] = OmnidevError
) -> Any:
    """Parse JSON text; NaN and Infinity are refused (JSON has neither), as are deep nesting
    and absurd numbers (:func:`check_magnitudes`; 1e400 parses to inf and is refused too)."""
    check_nesting(text, path, what, error)

    def constant(name: str) -> float:
        raise error(f"{path}: {name} is not a JSON number; not a valid {what}")

    def real(raw: str) -> float:
        value = float(raw)
        if not math.isfinite(value):
            raise error(f"{path}: {raw[:40]} overflows a float; not a valid {what}")
        return value

    def integer(raw: str) -> int:
        digits = len(raw.lstrip("-"))
        if digits > 19:
            raise error(f"{path}: an integer of {digits} digits is beyond 64 bits; not a {what}")
        return int(raw)

    try:
        doc = json.loads(text, parse_constant=constant, parse_float=real, parse_int=integer)
    except json.JSONDecodeError as exc:
        raise error(
            f"{path}: not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None
    except RecursionError:
        raise error(f"{path}: nested too deeply; not a {what}") from None
    check_magnitudes(doc, path, what, error)
    return doc


def read_json(path: Path | str, what: str, *, error: type[OmnidevError] = OmnidevError) -> Any:
    """:func:`read_text` then :func:`loads_json`."""
    return loads_json(read_text(path, what, error=error), path, what, error)


def read_gzip(
    path: Path | str,
    what: str,
    *,
    error: type[OmnidevError] = OmnidevError,
    limit: int = MAX_TEXT_BYTES,
) -> bytes:
    """The inflated bytes of a ``.gz`` file; refuse one that is corrupt or inflates past
    ``limit`` bytes, so that a compressed bomb never reaches a reader (cv2.FileStorage)
    that would inflate all of it into memory."""
    data = read_bytes(path, what, error=error, limit=limit)  # a file at all, and not huge
    out = []
    total = 0
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
            while chunk := fh.read(1 << 20):
                total += len(chunk)
                if total > limit:
                    raise error(
                        f"{path}: inflates to more than {_describe_size(limit)}; "
                        f"larger than any {what}"
                    )
                out.append(chunk)
    except (OSError, EOFError, zlib.error) as exc:
        raise error(f"{path}: not a readable gzip file ({exc})") from None
    return b"".join(out)
