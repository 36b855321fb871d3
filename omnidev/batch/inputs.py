"""What a batch job is given: inputs from globs and manifest files, their cameras and views.

An item on the command line is a path, a glob (``archive/**/*.mp4``) or a
manifest file (``.csv``, or ``.jsonl`` / ``.ndjson``: JSON lines), whose rows
name ``input`` (a path or glob, relative to the manifest's folder) and
optionally ``camera`` (a calibration file) and ``views`` (``;``-separated in
CSV, a list or a ``;``-separated string in JSON); a row without them takes the
command's ``--camera`` and ``--view``. A view is ``[NAME=]SPEC`` with SPEC in
omnidev.viewspec's syntax; NAME (default: the view's kind, numbered when two
share one) names the output folder.

Outputs go to ``OUT/NAME/REL`` with REL the input's path relative to the
inputs' common folder and the output format's suffix, so an archive's folder
tree is kept under each view. A row that cannot be used (no such file, a bad
view, a glob matching nothing) becomes a :class:`BadInput` that the job
reports by name while the rest run.
"""

from __future__ import annotations

import csv
import glob
import io
import json
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from omnidev.errors import OmnidevError
from omnidev.sources import IMAGE_SUFFIXES
from omnidev.viewspec import parse_view

MANIFEST_SUFFIXES = {".csv", ".jsonl", ".ndjson"}
VIDEO_FORMATS = (".mp4", ".mkv", ".mov", ".avi")
_NAMED = re.compile(r"^([A-Za-z0-9_.-]+)=([A-Za-z]+:.*)$")

InputKind = Literal["video", "image"]


@dataclass(frozen=True)
class NamedView:
    """One view of a job: its output folder name and its description (omnidev.viewspec)."""

    name: str
    spec: str


@dataclass(frozen=True)
class BatchInput:
    """One input file with its camera and views (all paths absolute).

    Attributes:
        path: the video or image file.
        camera: its calibration file.
        views: the views to make of it, in output order.
        origin: where it was named, for messages (``"manifest.csv row 3"``, a glob).
        kind: ``video`` or ``image`` (by the file's suffix).
    """

    path: Path
    camera: Path
    views: tuple[NamedView, ...]
    origin: str
    kind: InputKind


@dataclass(frozen=True)
class BadInput:
    """An input that cannot be run: ``name`` as the user gave it, ``reason`` one line."""

    name: str
    reason: str


def input_kind(path: Path) -> InputKind:
    return "image" if path.suffix.lower() in IMAGE_SUFFIXES else "video"


def name_views(specs: Sequence[str], where: str) -> tuple[NamedView, ...]:
    """``[NAME=]SPEC`` items -> views with unique names; each SPEC is checked by parse_view.

    >>> [v.name for v in name_views(["panorama:64x16", "plane:32x24,d=1,w=1,z=-1:0",
    ...                              "wide=panorama:128x32"], "--view")]
    ['panorama', 'plane', 'wide']
    >>> [v.name for v in name_views(["panorama:64x16", "panorama:32x8"], "--view")]
    ['panorama-1', 'panorama-2']
    """
    named: list[tuple[str | None, str]] = []
    for item in specs:
        item = item.strip()
        m = _NAMED.match(item)
        name, spec = (m.group(1), m.group(2)) if m else (None, item)
        parse_view(spec)  # raises ViewSpecError naming the spec
        named.append((name, spec))
    if not named:
        raise OmnidevError(f"{where}: no views")
    kinds = [spec.partition(":")[0].strip().lower() for _, spec in named]
    out: list[NamedView] = []
    for (name, spec), kind in zip(named, kinds, strict=True):
        if name is None:
            same = [i for i, (n, _) in enumerate(named) if n is None and kinds[i] == kind]
            name = kind if len(same) == 1 else f"{kind}-{same.index(len(out)) + 1}"
        out.append(NamedView(name, spec))
    names = [v.name for v in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise OmnidevError(f"{where}: two views are named {dup[0]!r}; give each its own NAME=")
    return tuple(out)


def _expand(pattern: str, base: Path) -> list[Path]:
    p = Path(os.path.expanduser(pattern))
    if not p.is_absolute():
        p = base / p
    if glob.has_magic(str(p)):
        return sorted(
            Path(f).resolve() for f in glob.glob(str(p), recursive=True) if Path(f).is_file()
        )
    return [p.resolve()]


def collect_inputs(
    items: Iterable[str],
    *,
    camera: Path | None,
    views: Sequence[str],
    cwd: Path | None = None,
) -> tuple[list[BatchInput], list[BadInput]]:
    """Expand command-line items (paths, globs, manifests) into inputs and bad inputs.

    ``camera`` and ``views`` are the command's defaults for items and rows that
    name none. Raises :class:`OmnidevError` for a mistake in the command itself
    (a bad ``--view``, a manifest that cannot be read); a bad row or a missing
    file is returned as a :class:`BadInput`.
    """
    base = (cwd or Path.cwd()).resolve()
    default_views = name_views(views, "--view") if views else ()
    default_camera = (base / camera).resolve() if camera is not None else None
    good: list[BatchInput] = []
    bad: list[BadInput] = []
    for item in items:
        path = Path(item)
        if path.suffix.lower() in MANIFEST_SUFFIXES and not glob.has_magic(item):
            g, b = _read_manifest(base / path, default_camera, default_views)
            good += g
            bad += b
            continue
        files = _expand(item, base)
        if not files:
            bad.append(BadInput(item, "no file matches"))
            continue
        for f in files:
            if default_camera is None or not default_views:
                raise OmnidevError(f"{item}: give --camera and --view (or use a manifest)")
            origin = item if glob.has_magic(item) else str(f)
            r = _make(f, default_camera, default_views, origin, item)
            (good if isinstance(r, BatchInput) else bad).append(r)  # type: ignore[arg-type]
    return _dedupe(good, bad)


def _make(
    f: Path, camera: Path, views: tuple[NamedView, ...], origin: str, name: str
) -> BatchInput | BadInput:
    label = name if str(f) == name or not glob.has_magic(name) else str(f)
    if not f.is_file():
        return BadInput(label, "file not found")
    if not camera.is_file():
        return BadInput(label, f"calibration file {camera} not found")
    return BatchInput(f, camera, views, origin, input_kind(f))


COLUMNS = ("input", "camera", "views")


def _not_utf8(text: str) -> bool:
    """True when ``text`` (decoded with surrogateescape) held bytes that are not UTF-8."""
    return any("\udc80" <= ch <= "\udcff" for ch in text)


def _rows(path: Path) -> list[tuple[int, dict[str, Any] | str]]:
    """(row number, fields or an error) of a manifest; row 1 is the first data row.

    A CSV row numbers its data rows (the header is not one), JSON lines count
    every line. Raises :class:`OmnidevError` naming the file for a manifest
    that cannot be used at all (unreadable, no header naming ``input``, an
    unknown column, no rows); a row that cannot be used is returned as its
    error: not UTF-8, not JSON, not an object, unknown keys, more fields than
    the header.
    """
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise OmnidevError(f"manifest {path}: file not found") from None
    except OSError as exc:
        raise OmnidevError(f"manifest {path}: cannot read it ({exc.strerror or exc})") from None
    text = data.decode("utf-8", errors="surrogateescape").removeprefix("\ufeff")
    rows = _csv_rows(path, text) if path.suffix.lower() == ".csv" else _json_rows(text)
    if not rows:
        raise OmnidevError(f"manifest {path}: no rows (an empty manifest)")
    return rows


def _csv_rows(path: Path, text: str) -> list[tuple[int, dict[str, Any] | str]]:
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next((r for r in reader if any(f.strip() for f in r)), None)
        if header is None:
            raise OmnidevError(f"manifest {path}: no rows (an empty manifest)")
        fields = [f.strip().lower() for f in header]
        if _not_utf8(",".join(fields)):
            raise OmnidevError(f"manifest {path}: its header is not UTF-8 text")
        if "input" not in fields:
            raise OmnidevError(
                f"manifest {path}: the header must name an 'input' column (and optionally "
                f"'camera', 'views'); found {', '.join(fields)}"
            )
        unknown = [f for f in fields if f not in COLUMNS]
        twice = sorted({f for f in fields if fields.count(f) > 1})
        if unknown or twice:
            what = f"unknown column {unknown[0]!r}" if unknown else f"two {twice[0]!r} columns"
            raise OmnidevError(f"manifest {path}: {what} (columns: {', '.join(COLUMNS)})")
        rows: list[tuple[int, dict[str, Any] | str]] = []
        for n, row in enumerate(reader, start=1):
            if not any(f.strip() for f in row):
                continue
            if _not_utf8(",".join(row)):
                rows.append((n, "not UTF-8 text"))
            elif len(row) > len(fields):
                rows.append(
                    (n, f"{len(row)} fields, the header has {len(fields)} (quote a field that "
                        'holds commas: "a;b,fov=90")')
                )  # fmt: skip
            else:
                rows.append((n, {k: v.strip() for k, v in zip(fields, row, strict=False)}))
    except csv.Error as exc:
        raise OmnidevError(f"manifest {path} line {reader.line_num}: {exc}") from None
    return rows


def _json_rows(text: str) -> list[tuple[int, dict[str, Any] | str]]:
    rows: list[tuple[int, dict[str, Any] | str]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if _not_utf8(line):
            rows.append((n, "not UTF-8 text"))
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as exc:
            rows.append((n, f"not JSON ({exc.msg} at column {exc.colno})"))
            continue
        if not isinstance(obj, dict):
            rows.append((n, "not a JSON object"))
            continue
        unknown = sorted(k for k in obj if k not in COLUMNS)
        if unknown:
            rows.append((n, f"unknown key {unknown[0]!r} (keys: {', '.join(COLUMNS)})"))
            continue
        if not all(isinstance(obj.get(k, ""), str) for k in ("input", "camera")):
            rows.append((n, "input and camera must be strings"))
            continue
        rows.append((n, obj))
    return rows


def _read_manifest(
    path: Path, camera: Path | None, views: tuple[NamedView, ...]
) -> tuple[list[BatchInput], list[BadInput]]:
    good: list[BatchInput] = []
    bad: list[BadInput] = []
    base = path.parent.resolve()
    line_word = "row" if path.suffix.lower() == ".csv" else "line"
    for n, row in _rows(path):
        where = f"{path.name} {line_word} {n}"
        if isinstance(row, str):
            bad.append(BadInput(where, row))
            continue
        name = str(row.get("input") or "").strip()
        if not name:
            bad.append(BadInput(where, "no input"))
            continue
        label = f"{name} ({where})"
        try:
            row_views = _row_views(row.get("views"), where) or views
        except OmnidevError as exc:
            bad.append(BadInput(label, str(exc)))
            continue
        cam_text = str(row.get("camera") or "").strip()
        row_camera = (base / os.path.expanduser(cam_text)).resolve() if cam_text else camera
        if row_camera is None or not row_views:
            bad.append(
                BadInput(label, "no camera or no views (give them in the row or the command)")
            )
            continue
        files = _expand(name, base)
        if not files:
            bad.append(BadInput(label, "no file matches"))
            continue
        for f in files:
            r = _make(f, row_camera, row_views, where, label if len(files) == 1 else str(f))
            (good if isinstance(r, BatchInput) else bad).append(r)  # type: ignore[arg-type]
    return good, bad


def _row_views(value: Any, where: str) -> tuple[NamedView, ...]:
    if value is None or value == "":
        return ()
    if isinstance(value, str):
        items = [v for v in value.split(";") if v.strip()]
    elif isinstance(value, list) and all(isinstance(v, str) for v in value):
        items = value
    else:
        raise OmnidevError("views must be a list of view strings or one ';'-separated string")
    return name_views(items, f"{where} views")


def _dedupe(good: list[BatchInput], bad: list[BadInput]) -> tuple[list[BatchInput], list[BadInput]]:
    """The same file named twice (a glob and a manifest) runs once, with its first views."""
    seen: set[Path] = set()
    out: list[BatchInput] = []
    for g in good:
        if g.path in seen:
            continue
        seen.add(g.path)
        out.append(g)
    return out, bad


def common_root(inputs: Sequence[BatchInput]) -> Path:
    """The deepest folder holding every input (outputs keep the tree below it)."""
    if not inputs:
        return Path("/")
    return Path(os.path.commonpath([str(i.path.parent) for i in inputs]))


def output_path(
    out_dir: Path,
    root: Path,
    item: BatchInput,
    view: NamedView,
    video_suffix: str,
    image_suffix: str,
) -> Path:
    """Where ``view`` of ``item`` goes: ``out_dir / view.name / relative path`` with its suffix."""
    rel = item.path.relative_to(root)
    suffix = image_suffix if item.kind == "image" else video_suffix
    return out_dir / view.name / rel.with_suffix(suffix)


def find_collisions(
    out_dir: Path, root: Path, inputs: Sequence[BatchInput], video_suffix: str, image_suffix: str
) -> list[BadInput]:
    """Inputs whose output would overwrite another's (``a.mp4`` and ``a.mkv`` -> ``a.mp4``)."""
    owner: dict[Path, Path] = {}
    bad: list[BadInput] = []
    for item in inputs:
        for v in item.views:
            p = output_path(out_dir, root, item, v, video_suffix, image_suffix)
            first = owner.setdefault(p, item.path)
            if first != item.path:
                bad.append(
                    BadInput(str(item.path), f"its output {p} is also {first}'s; rename one")
                )
                break
    return bad
