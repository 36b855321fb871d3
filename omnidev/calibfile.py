"""Calibration files: cv2.FileStorage (YAML, XML or JSON, optionally .gz) with a ``kind``.

Every calibration file omnidev writes has two top-level nodes besides its data:
``kind`` (the camera kind, which names the unwarper plugin that reads it) and
``format_version`` (an integer the plugin checks). :func:`load_camera` reads
the kind and hands the file to the registered unwarper.
"""

from __future__ import annotations

import gzip
import math
import re
import zlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev import registry
from omnidev.atomic import atomic_path
from omnidev.camera import CameraModel
from omnidev.errors import CalibrationError
from omnidev.inputfile import MAX_MAGNITUDE, check_nesting, read_bytes, read_gzip

UNWARPERS = "omnidev.unwarpers"

MAX_CALIBRATION_BYTES = 1 << 30
"""Largest calibration file read, and what a ``.gz`` one may inflate to (1 GiB): a
format-1 pano-table file stores its table entries, 67 MiB gzipped at 1920x1920 (the
bench's), several times that at 3840; the 64 MiB limit of other text inputs refused them."""


@contextmanager
def open_storage(path: Path) -> Iterator[cv2.FileStorage]:
    """Open a FileStorage for reading; a clear error for a missing or unparsable file."""
    path = Path(path)
    what = "calibration file"
    if path.name.lower().endswith(".gz"):
        data = read_gzip(path, what, error=CalibrationError, limit=MAX_CALIBRATION_BYTES)
    else:  # a regular file, not huge
        data = read_bytes(path, what, error=CalibrationError, limit=MAX_CALIBRATION_BYTES)
    nul = data.find(b"\0")
    if nul >= 0:  # cv2.FileStorage would stop reading there and take the rest as absent
        line = data.count(b"\n", 0, nul) + 1
        raise CalibrationError(f"{path}: line {line}: a NUL byte; not a {what} (a binary file?)")
    text = data.decode("latin-1")
    check_nesting(text, path, what, CalibrationError)
    _check_matrix_headers(text, path)
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        text = str(exc.__cause__ or exc)
        msg = text.split("error:", 1)[-1].strip().splitlines()[0] if text else "parse error"
        raise CalibrationError(f"{path}: not a readable OpenCV FileStorage file ({msg})") from None
    if not fs.isOpened():
        raise CalibrationError(f"{path}: not a readable OpenCV FileStorage file")
    try:
        yield fs
    finally:
        fs.release()


_DIM = re.compile(r"(?:\b(rows|cols)\s*:\s*|<(rows|cols)>\s*)([^\s,}<]*)")
MAX_MATRIX_ELEMENTS = 1 << 26
"""Largest matrix a calibration file may declare (64 Mi elements; a pano-table is far less)."""


def _check_matrix_headers(text: str, path: Path) -> None:
    """Refuse an opencv-matrix whose rows/cols are not plausible whole numbers *before*
    cv2.FileStorage reads it (it allocates rows x cols first, whatever the data holds)."""
    dims: list[int] = []
    for m in _DIM.finditer(text):
        raw = m.group(3)
        try:
            n = int(raw)
        except ValueError:
            raise CalibrationError(
                f"{path}: matrix {m.group(1) or m.group(2)} {raw!r} is not a whole number"
            ) from None
        if not 0 <= n <= MAX_MATRIX_ELEMENTS:
            raise CalibrationError(
                f"{path}: matrix {m.group(1) or m.group(2)} {n} is not a plausible size"
            )
        dims.append(n)
        if len(dims) % 2 == 0 and dims[-1] * dims[-2] > MAX_MATRIX_ELEMENTS:
            raise CalibrationError(
                f"{path}: a matrix of {dims[-2]}x{dims[-1]} is not a plausible size"
            )


def read_string(fs: cv2.FileStorage, path: Path, key: str) -> str:
    node = fs.getNode(key)
    if node.empty() or not node.isString():
        raise CalibrationError(f"{path}: missing text key {key!r}")
    try:
        return str(node.string())
    except UnicodeDecodeError:  # e.g. a YAML escape "\xde" that makes no UTF-8 character
        raise CalibrationError(f"{path}: text key {key!r} is not UTF-8 text") from None


def read_real(fs: cv2.FileStorage, path: Path, key: str) -> float:
    node = fs.getNode(key)
    if node.empty() or not (node.isReal() or node.isInt()):
        raise CalibrationError(f"{path}: missing number key {key!r}")
    value = float(node.real())
    if not np.isfinite(value):
        raise CalibrationError(f"{path}: key {key!r} is not finite")
    if abs(value) > MAX_MAGNITUDE:
        raise CalibrationError(f"{path}: key {key!r} is {value:g}, beyond +-{MAX_MAGNITUDE:g}")
    return value


_MATRIX_KEYS = ("rows", "cols", "sizes", "dt", "data")
_DT = re.compile(r"([1-9][0-9]*)?[ucwsifdh]")


def matrix_node_problem(node: cv2.FileNode) -> str | None:
    """What keeps an ``opencv-matrix`` (``rows``, ``cols``) or ``opencv-nd-matrix``
    (``sizes``) map node from being a whole matrix ("no cols", "holds 3 values, not 1 x
    2 of d"), or None. Checked before ``FileNode.mat()``, which on a matrix without
    ``cols`` can corrupt the process's heap (a crash later, in a forked child: fuzz seed
    49) rather than raise."""
    nd = not node.getNode("sizes").empty()
    need = ("sizes", "dt", "data") if nd else ("rows", "cols", "dt", "data")
    parts = {k: node.getNode(k) for k in need}
    missing = [k for k, n in parts.items() if n.empty()]
    if missing:
        return f"no {', '.join(missing)}"
    if nd:
        sizes = parts["sizes"]
        items = [sizes.at(i) for i in range(sizes.size())] if sizes.isSeq() else [sizes]
        if not all(n.isInt() for n in items):
            return "sizes are not whole numbers"
        dims = [int(n.real()) for n in items]
    elif parts["rows"].isInt() and parts["cols"].isInt():
        dims = [int(parts["rows"].real()), int(parts["cols"].real())]
    else:
        return "rows and cols are not whole numbers"
    try:
        dt = parts["dt"].string() if parts["dt"].isString() else ""
    except UnicodeDecodeError:  # bytes that make no UTF-8 text
        dt = "?"
    m = _DT.fullmatch(dt)
    if m is None:
        return f"element type dt {dt!r} is not one OpenCV reads (d, f, i, u, 3d, ...)"
    data = parts["data"]
    have = data.size() if data.isSeq() else (0 if data.isNone() else 1)  # XML: <data></data>
    if any(d < 0 for d in dims) or have != math.prod(dims) * int(m.group(1) or 1):
        return f"holds {have} values, not {' x '.join(map(str, dims))} of {dt}"
    return None


def check_matrix_node(node: cv2.FileNode, path: Path, key: str) -> None:
    """Raise where map node ``key`` has a matrix's keys but is no whole matrix
    (:func:`matrix_node_problem`); call it before ``node.mat()``."""
    # (FileNode.keys() decodes every key as UTF-8: a damaged key name would raise there)
    if node.isMap() and any(not node.getNode(k).empty() for k in _MATRIX_KEYS):
        problem = matrix_node_problem(node)
        if problem is not None:
            raise CalibrationError(f"{path}: matrix key {key!r} is incomplete ({problem})")


def read_mat(fs: cv2.FileStorage, path: Path, key: str) -> np.ndarray[Any, Any]:
    node = fs.getNode(key)
    check_matrix_node(node, path, key)
    try:
        mat = None if node.empty() else node.mat()
    except cv2.error:  # e.g. an opencv-matrix node cut off before its data
        raise CalibrationError(f"{path}: matrix key {key!r} is incomplete") from None
    if mat is None:
        raise CalibrationError(f"{path}: missing matrix key {key!r}")
    arr = np.asarray(mat)
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{path}: matrix {key!r} has non-finite values")
    biggest = float(np.max(np.abs(arr.astype(np.float64)))) if arr.size else 0.0
    if biggest > MAX_MAGNITUDE:
        raise CalibrationError(
            f"{path}: matrix {key!r} has a value of {biggest:g}, beyond +-{MAX_MAGNITUDE:g}"
        )
    return arr


_KIND_PATTERNS = (
    re.compile(rb"^kind:[ \t]*\"?([A-Za-z0-9_.-]+)\"?[ \t]*\r?$", re.M),  # YAML
    re.compile(rb"<kind>\s*\"?([A-Za-z0-9_.-]+)\"?\s*</kind>"),  # XML
    re.compile(rb"^\s*\"kind\"\s*:\s*\"([A-Za-z0-9_.-]+)\"", re.M),  # JSON
)
PEEK_BYTES = 4096


def _peek_kind(path: Path) -> str | None:
    """The top-level ``kind`` from the file's first bytes (written first), or None."""
    try:
        if path.name.endswith(".gz"):
            with gzip.open(path, "rb") as fh:
                head = fh.read(PEEK_BYTES)
        else:
            with path.open("rb") as fh:
                head = fh.read(PEEK_BYTES)
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error):
        return None  # open_storage reads the whole file and says what is wrong with it
    for pat in _KIND_PATTERNS:
        m = pat.search(head)
        if m is not None:
            return m.group(1).decode("ascii")
    return None


def read_kind(path: Path) -> str:
    """The ``kind`` of a calibration file.

    Read from the file's first bytes when it is there (omnidev writes it
    first), so that :func:`load_camera` does not parse a large file twice;
    otherwise by parsing the file.
    """
    path = Path(path)
    if path.is_file():
        kind = _peek_kind(path)
        if kind is not None:
            return kind
    with open_storage(path) as fs:
        return read_string(fs, path, "kind")


def check_header(fs: cv2.FileStorage, path: Path, kind: str, version: int) -> None:
    """Raise unless the file is of ``kind`` and exactly format ``version``."""
    got = read_string(fs, path, "kind")
    if got != kind:
        raise CalibrationError(f"{path}: a calibration of kind {got!r}, not {kind!r}")
    v = int(read_real(fs, path, "format_version"))
    if v != version:
        raise CalibrationError(
            f"{path}: {kind} format version {v}; this omnidev reads version {version}"
        )


def write_storage(
    path: Path, kind: str, version: int, nodes: Mapping[str, Any], *, force: bool = False
) -> None:
    """Write ``nodes`` (str, int, float, ndarray) atomically with the kind/version header."""
    with atomic_path(Path(path), force=force) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        if not fs.isOpened():
            raise CalibrationError(f"{path}: cannot write (unknown extension? use .yml or .yml.gz)")
        fs.write("kind", kind)
        fs.write("format_version", version)
        for key, value in nodes.items():
            if isinstance(value, np.ndarray):
                fs.write(key, value)
            elif isinstance(value, bool | int):
                fs.write(key, int(value))
            elif isinstance(value, float):
                fs.write(key, value)
            else:
                fs.write(key, str(value))
        fs.release()


def load_camera(path: Path | str, options: Mapping[str, str] | None = None) -> CameraModel:
    """Load a calibration of any registered kind: the file's ``kind`` picks the unwarper.

    Raises :class:`CalibrationError` for unreadable files and
    :class:`omnidev.errors.PluginError` naming the installed kinds for an
    unknown kind.
    """
    path = Path(path)
    kind = read_kind(path)
    unwarper = registry.get(UNWARPERS, kind)
    if isinstance(unwarper, type):
        unwarper = unwarper()
    camera: CameraModel = unwarper.load(path, dict(options or {}))
    return camera
