"""The evaluation framework: tasks, per-scene results, parallel runs, pooled figures.

See :mod:`omnidev.evaluation` for how a task is written and added.
"""

from __future__ import annotations

import importlib
import math
import multiprocessing
import pkgutil
import signal
import time
import traceback
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from omnidev.errors import OmnidevError

Status = Literal["ok", "refused", "error"]


@dataclass
class SceneResult:
    """One scene's outcome.

    ``seed``: the scene seed (replay it with ``--scene-seed``). ``classes``: labels
    (e.g. ``{"camera": ">=640x480", "codec": "h264"}``) by which results are also
    reported apart. ``status``: ``ok``, ``refused`` (the method declined, with
    ``message``) or ``error`` (an unexpected exception: a bug). ``metrics``: named
    figures (units in the name or the task's doc, e.g. ``radial.rms``), NaN when
    not measured. ``counts``: integers that pool by summing (detections, false
    positives). ``flags``: booleans (e.g. ``in_spec``). ``notes``: text (e.g. the
    message of a second method that refused). ``seconds``: wall time.
    """

    seed: int
    classes: dict[str, str] = field(default_factory=dict)
    status: Status = "ok"
    message: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    flags: dict[str, bool] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN as null)."""
        d = asdict(self)
        d["metrics"] = {k: _num(v) for k, v in self.metrics.items()}
        return d


RunScene = Callable[[int, Mapping[str, Any], Path | None], SceneResult]
Summarize = Callable[[Sequence[SceneResult], Mapping[str, Any]], dict[str, Any]]


@dataclass(frozen=True)
class Task:
    """An evaluation task (see :mod:`omnidev.evaluation`)."""

    name: str
    help: str
    run_scene: RunScene
    summarize: Summarize | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    headline: tuple[str, ...] = ()
    choices: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    """The values a text option may take (checked by :func:`typed_options`)."""
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    """The closed range of a number option (checked by :func:`typed_options`)."""
    check: Callable[[Mapping[str, Any]], None] | None = None
    """Checks the typed options together; raises OmnidevError naming the option."""


def _num(v: float) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def task_names() -> list[str]:
    """Names of the tasks in omnidev/evaluation/tasks/."""
    from omnidev.evaluation import tasks

    return sorted(
        m.name for m in pkgutil.iter_modules(tasks.__path__) if not m.name.startswith("_")
    )


def load_task(name: str) -> Task:
    """The task ``name``; an OmnidevError lists the known ones."""
    if name not in task_names():
        raise OmnidevError(f"unknown evaluation task {name!r}; known: {', '.join(task_names())}")
    module = importlib.import_module(f"omnidev.evaluation.tasks.{name}")
    task = getattr(module, "TASK", None)
    if not isinstance(task, Task):
        raise OmnidevError(f"omnidev.evaluation.tasks.{name} defines no TASK")
    return task


def typed_options(task: Task, given: Mapping[str, str]) -> dict[str, Any]:
    """The task's options with ``given`` (text values) applied; errors name the key."""
    out = dict(task.options)
    for key, text in given.items():
        if key not in out:
            known = ", ".join(sorted(out)) or "none"
            raise OmnidevError(f"task {task.name}: unknown option {key!r} (options: {known})")
        default = out[key]
        try:
            if isinstance(default, bool):
                if text.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(text)
                out[key] = text.lower() in ("true", "1", "yes")
            elif isinstance(default, int):
                out[key] = int(text)
            elif isinstance(default, float):
                out[key] = float(text)
            else:
                out[key] = text
        except ValueError:
            kind = type(default).__name__
            raise OmnidevError(f"task {task.name}: option {key}={text!r} is not a {kind}") from None
        value = out[key]
        if isinstance(value, float) and not math.isfinite(value):
            raise OmnidevError(f"task {task.name}: option {key}={text!r} must be finite")
        if key in task.choices and value not in task.choices[key]:
            known = ", ".join(task.choices[key])
            raise OmnidevError(f"task {task.name}: option {key}={text!r}; choose from {known}")
        if key in task.ranges and not isinstance(value, bool):
            lo, hi = task.ranges[key]
            if not lo <= value <= hi:
                raise OmnidevError(
                    f"task {task.name}: option {key}={text!r} must be {lo:g}..{hi:g}"
                )
    if task.check is not None:
        task.check(out)
    return out


def run_one(task: Task, seed: int, options: Mapping[str, Any], outdir: Path | None) -> SceneResult:
    """Run one scene; an unexpected exception becomes status ``error`` with its last frame."""
    t0 = time.perf_counter()
    try:
        res = task.run_scene(seed, options, outdir)
    except Exception as exc:  # a bug in the method or the task, reported, never hidden
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
        msg = f"{type(exc).__name__}: {exc}"[:300]
        res = SceneResult(seed, status="error", message=msg + where)
    res.seconds = time.perf_counter() - t0
    return res


def _worker_init() -> None:
    """A pool worker ends on SIGTERM by the kernel's default action. The handler it inherits
    from omnidev's CLI raises in Python's main thread only, and the kernel may hand the
    signal to an OpenCV or BLAS thread instead, leaving an idle worker waiting for work
    forever (and ``omnidev eval --jobs 2`` hung in Pool.terminate after its last scene)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _worker(args: tuple[str, int, dict[str, Any]]) -> SceneResult:
    name, seed, options = args
    return run_one(load_task(name), seed, options, None)


def run_scenes(
    task: Task,
    seeds: Sequence[int],
    options: Mapping[str, Any],
    *,
    jobs: int = 1,
    progress: bool = True,
) -> list[SceneResult]:
    """Results of ``task`` on ``seeds`` (in seed order), on ``jobs`` worker processes."""
    from tqdm import tqdm

    bar = tqdm(total=len(seeds), desc=f"eval {task.name}", unit="scene", disable=not progress)
    results: list[SceneResult] = []
    try:
        if jobs <= 1:
            for s in seeds:
                results.append(run_one(task, s, options, None))
                bar.update()
        else:
            ctx = multiprocessing.get_context("fork")
            with ctx.Pool(jobs, initializer=_worker_init, maxtasksperchild=20) as pool:
                work = [(task.name, s, dict(options)) for s in seeds]
                for r in pool.imap_unordered(_worker, work):
                    results.append(r)
                    bar.update()
                pool.close()  # the workers end on their own; terminate() only on an error
                pool.join()
    finally:
        bar.close()
    return sorted(results, key=lambda r: r.seed)


# ---------------------------------------------------------------- pooling


def stats(values: Iterable[float]) -> dict[str, float | int | None]:
    """n, mean, median, p95, max of the finite values (None when there are none)."""
    a = np.array([v for v in values if v is not None and math.isfinite(v)], float)
    if a.size == 0:
        return {"n": 0, "mean": None, "median": None, "p95": None, "max": None}
    return {
        "n": int(a.size),
        "mean": float(a.mean()),
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
    }


def worst(results: Sequence[SceneResult], metric: str, k: int = 5) -> list[dict[str, Any]]:
    """The k scenes with the largest ``metric``: seed, value, classes."""
    have = [r for r in results if math.isfinite(r.metrics.get(metric, math.nan))]
    have.sort(key=lambda r: r.metrics[metric], reverse=True)
    return [{"seed": r.seed, "value": r.metrics[metric], "classes": r.classes} for r in have[:k]]


def refusals(results: Sequence[SceneResult], status: Status = "refused") -> list[dict[str, Any]]:
    """Messages of refused (or errored) scenes, grouped: message, count, seeds."""
    groups: dict[str, list[int]] = defaultdict(list)
    for r in results:
        if r.status == status:
            groups[r.message].append(r.seed)
    out = [{"message": m, "count": len(s), "seeds": s} for m, s in groups.items()]
    return sorted(out, key=lambda d: -int(d["count"]))


def pooled(results: Sequence[SceneResult]) -> dict[str, Any]:
    """Counts by status, every metric's statistics and worst scenes, summed counts."""
    names = sorted({k for r in results for k in r.metrics})
    cnames = sorted({k for r in results for k in r.counts})
    return {
        "scenes": len(results),
        "ok": sum(r.status == "ok" for r in results),
        "refused": sum(r.status == "refused" for r in results),
        "errors": sum(r.status == "error" for r in results),
        "metrics": {m: stats(r.metrics.get(m, math.nan) for r in results) for m in names},
        "worst": {m: worst(results, m) for m in names},
        "counts": {c: int(sum(r.counts.get(c, 0) for r in results)) for c in cnames},
        "seconds_per_scene": stats(r.seconds for r in results),
    }


def by_class(results: Sequence[SceneResult], headline: Sequence[str]) -> dict[str, Any]:
    """For each class key and value: scenes, refused, errors and the headline metrics."""
    out: dict[str, Any] = {}
    keys = sorted({k for r in results for k in r.classes})
    for key in keys:
        groups: dict[str, list[SceneResult]] = defaultdict(list)
        for r in results:
            groups[r.classes.get(key, "?")].append(r)
        out[key] = {
            value: {
                "scenes": len(rs),
                "refused": sum(r.status == "refused" for r in rs),
                "errors": sum(r.status == "error" for r in rs),
                "metrics": {m: stats(r.metrics.get(m, math.nan) for r in rs) for m in headline},
            }
            for value, rs in sorted(groups.items())
        }
    return out


def evaluate(
    task: Task,
    *,
    scenes: int,
    seed: int,
    options: Mapping[str, Any] | None = None,
    jobs: int = 1,
    progress: bool = True,
) -> dict[str, Any]:
    """Run ``task`` over ``scenes`` scenes from ``seed`` and pool: the report document."""
    if scenes < 1:
        raise OmnidevError(f"--scenes {scenes}: at least 1")
    opts = dict(task.options) if options is None else dict(options)
    seeds = list(range(seed, seed + scenes))
    t0 = time.perf_counter()
    results = run_scenes(task, seeds, opts, jobs=jobs, progress=progress)
    return report(task, results, opts, jobs=jobs, seconds=time.perf_counter() - t0)


def report(
    task: Task,
    results: Sequence[SceneResult],
    options: Mapping[str, Any],
    *,
    jobs: int = 1,
    seconds: float = math.nan,
) -> dict[str, Any]:
    """The report document of ``results`` (sorted by seed): pooled figures, refusals,
    errors, classes, the task's summary and every scene."""
    results = sorted(results, key=lambda r: r.seed)
    opts = dict(options)
    seeds = [r.seed for r in results]
    doc: dict[str, Any] = {
        "task": task.name,
        "seed": seeds[0],
        "scenes": len(results),
        "seed_range": [seeds[0], seeds[-1]],
        "options": opts,
        "jobs": jobs,
        "seconds": seconds,
        "pooled": pooled(results),
        "refusals": refusals(results),
        "errors": refusals(results, "error"),
        "classes": by_class(results, task.headline),
    }
    if task.summarize is not None:
        doc["summary"] = task.summarize(results, opts)
    doc["per_scene"] = [r.to_dict() for r in results]
    return doc


def result_from_dict(d: Mapping[str, Any]) -> SceneResult:
    """A :class:`SceneResult` from its :meth:`SceneResult.to_dict` (null figures: NaN)."""
    return SceneResult(
        seed=int(d["seed"]),
        classes={str(k): str(v) for k, v in d.get("classes", {}).items()},
        status=d.get("status", "ok"),
        message=str(d.get("message", "")),
        metrics={
            str(k): math.nan if v is None else float(v) for k, v in d.get("metrics", {}).items()
        },
        counts={str(k): int(v) for k, v in d.get("counts", {}).items()},
        flags={str(k): bool(v) for k, v in d.get("flags", {}).items()},
        notes={str(k): str(v) for k, v in d.get("notes", {}).items()},
        seconds=float(d.get("seconds", 0.0)),
    )


def merge_reports(task: Task, docs: Sequence[tuple[str, Mapping[str, Any]]]) -> dict[str, Any]:
    """One report from several (name, report document) of the same task and options, e.g.
    a long run made in chunks of seeds; a scene seed in two of them is an error."""
    if not docs:
        raise OmnidevError("nothing to merge")
    results: list[SceneResult] = []
    seen: dict[int, str] = {}
    options: Mapping[str, Any] | None = None
    seconds = 0.0
    for name, doc in docs:
        if not isinstance(doc, Mapping) or doc.get("task") != task.name or "per_scene" not in doc:
            raise OmnidevError(f"{name}: not an 'omnidev eval {task.name}' report")
        if options is None:
            options = doc.get("options", {})
        elif doc.get("options", {}) != options:
            raise OmnidevError(f"{name}: task options {doc.get('options')} differ from {options}")
        try:
            rs = [result_from_dict(d) for d in doc["per_scene"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise OmnidevError(f"{name}: a per_scene entry is malformed ({exc})") from None
        for r in rs:
            if r.seed in seen:
                raise OmnidevError(f"{name}: scene seed {r.seed} is also in {seen[r.seed]}")
            seen[r.seed] = name
        results += rs
        seconds += float(doc.get("seconds") or 0.0)
    if not results:
        raise OmnidevError("the reports hold no scenes")
    doc = report(task, results, options or {}, jobs=0, seconds=seconds)
    doc["merged_from"] = [name for name, _ in docs]
    return doc


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def report_text(doc: Mapping[str, Any], headline: Sequence[str]) -> str:
    """The report as text: totals, acceptance, headline figures, classes, refusals, worst."""
    p = doc["pooled"]
    lines = [
        f"omnidev eval {doc['task']}: {doc['scenes']} scenes, seeds "
        f"{doc['seed_range'][0]}..{doc['seed_range'][1]}, {doc['seconds']:.0f} s",
        f"  ok {p['ok']}, refused {p['refused']}, errors {p['errors']}",
    ]
    summary = doc.get("summary") or {}
    acc = summary.get("acceptance") or []
    if acc:
        lines.append("acceptance:")
        for a in acc:
            mark = "PASS" if a["passed"] else "FAIL"
            lines.append(f"  [{mark}] {a['name']}: {_fmt(a['value'])} (bound {a['bound']})")
    for key, val in summary.items():
        if key == "acceptance":
            continue
        lines.append(f"{key}: {val}" if not isinstance(val, dict) else f"{key}:")
        if isinstance(val, dict):
            for k2, v2 in val.items():
                lines.append(f"  {k2}: {_fmt(v2) if not isinstance(v2, dict) else v2}")
    if headline:
        lines.append(f"{'figure':<28}{'n':>5}{'median':>9}{'p95':>9}{'max':>9}  worst seeds")
        for m in headline:
            s = p["metrics"].get(m)
            if s is None:
                continue
            w = ", ".join(str(x["seed"]) for x in p["worst"].get(m, [])[:3])
            lines.append(
                f"{m:<28}{s['n']:>5}{_fmt(s['median']):>9}{_fmt(s['p95']):>9}"
                f"{_fmt(s['max']):>9}  {w}"
            )
    if headline:
        first = headline[0]
        lines.append(f"by class ({first}: median / p95 / max; refused / scenes):")
        for key, groups in doc["classes"].items():
            for value, g in groups.items():
                s = g["metrics"].get(first, {})
                lines.append(
                    f"  {key}={value:<18} {g['refused']:>3} / {g['scenes']:<4} "
                    f"{_fmt(s.get('median'))} / {_fmt(s.get('p95'))} / {_fmt(s.get('max'))}"
                )
    for title, items in (("refusals", doc["refusals"]), ("errors", doc["errors"])):
        if items:
            lines.append(f"{title}:")
            for it in items[:12]:
                seeds = ", ".join(map(str, it["seeds"][:8]))
                lines.append(f"  {it['count']:>3} x {it['message']}  (seeds {seeds})")
    return "\n".join(lines)
