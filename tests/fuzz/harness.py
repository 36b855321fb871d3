"""The fuzz suite's runner: cases through the real CLI in forked children, classified.

A :class:`Case` is one command line plus the files it needs; :func:`run_cases`
materializes each case's files in its own folder, sends the case to a pool of
fork servers (tests/fuzz/server.py) and classifies what happened:

| class       | meaning                                                                  |
|-------------|--------------------------------------------------------------------------|
| clean       | non-zero exit, no traceback, the last line is ``PROG: error: ...``       |
| accepted    | exit 0 where acceptance is allowed (``expect="any"``)                    |
| silent      | exit 0 where the input must be refused (``expect="refuse"``)             |
| traceback   | a Python traceback on standard error                                     |
| hang        | still running at the case's timeout (killed)                             |
| memory      | peak resident memory over the limit, or a MemoryError / allocation error |
| crash       | killed by a signal (segfault, abort)                                     |
| unclear     | non-zero exit without a ``PROG: error:`` last line                       |

Only ``clean`` and ``accepted`` are good.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import stat
import subprocess
import sys
import threading
from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

REPO = Path(__file__).resolve().parents[2]
GOOD = ("clean", "accepted")
MEMORY_LIMIT_BYTES = 1 << 30
"""A case whose peak resident memory passes this is classed ``memory``."""
ADDRESS_SPACE_EXTRA = 3 << 29
"""Address space a child may map beyond the server's own (1.5 GiB): a safety net only."""
NOBODY = 65534

# A file entry: bytes to write, or a special thing to make at that name.
Special = Literal["dir", "symlink-loop", "dev-zero", "dangling", "sparse"]


@dataclass(frozen=True)
class Unreadable:
    """A file with these bytes and mode 000; the case runs as user nobody (see :class:`Case`)."""

    data: bytes


FileSpec = bytes | Special | Unreadable


@dataclass
class Case:
    """One command line through the CLI.

    Attributes:
        command: the command it exercises ("unwarp", "calibrate pano-table"), for the counts.
        what: the malformed input ("rig: non-UTF-8"), printed for a failure.
        argv: the arguments after ``omnidev``; ``{d}`` is replaced by the case's folder.
        files: files made in the case's folder first (name -> bytes or a special kind).
        expect: "refuse" (exit 0 is a silent acceptance) or "any".
        timeout: seconds before the case counts as a hang.
    """

    command: str
    what: str
    argv: Sequence[str]
    files: dict[str, FileSpec] = field(default_factory=dict)
    expect: Literal["refuse", "any"] = "refuse"
    timeout: float = 60.0  # wall time: generous, the test machine may be loaded
    env: dict[str, str] = field(default_factory=dict)

    @property
    def as_nobody(self) -> bool:
        return any(isinstance(v, Unreadable) for v in self.files.values())


@dataclass
class Outcome:
    case: Case
    cls: str
    rc: int | None
    seconds: float
    maxrss_kb: int
    stderr: str
    cpu: float = 0.0

    def describe(self) -> str:
        last = [ln for ln in self.stderr.strip().splitlines() if ln.strip()][-6:]
        return (
            f"[{self.cls}] omnidev {' '.join(self.case.argv)}  ({self.case.what}; rc {self.rc}, "
            f"{self.seconds:.1f} s, {self.maxrss_kb / 1024:.0f} MiB)\n    " + "\n    ".join(last)
        )


def classify(case: Case, reply: dict[str, Any]) -> str:
    """The class of one reply (see the module docstring)."""
    err: str = reply["stderr"]
    if reply["timed_out"]:
        return "hang"
    memory_words = ("MemoryError", "Insufficient memory", "Failed to allocate", "bad_alloc")
    if reply["maxrss_kb"] * 1024 > MEMORY_LIMIT_BYTES or any(w in err for w in memory_words):
        return "memory"
    if "Traceback (most recent call last)" in err:
        return "traceback"
    if reply["rc"] is None:
        return "crash"
    if reply["rc"] == 0:
        return "silent" if case.expect == "refuse" else "accepted"
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    if not lines or ": error:" not in lines[-1] or not lines[-1].startswith("omnidev"):
        return "unclear"
    return "clean"


def _make(folder: Path, name: str, spec: FileSpec) -> None:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(spec, bytes):
        path.write_bytes(spec)
    elif isinstance(spec, Unreadable):
        path.write_bytes(spec.data)
        path.chmod(0)
    elif spec == "dir":
        path.mkdir()
        (path / "inside.txt").write_text("a file inside a folder\n")
    elif spec == "symlink-loop":
        other = path.with_name(path.name + ".loop")
        os.symlink(other.name, path)
        os.symlink(path.name, other)
    elif spec == "dev-zero":
        os.symlink("/dev/zero", path)
    elif spec == "sparse":
        with open(path, "wb") as fh:
            fh.truncate(4 << 30)
    elif spec == "dangling":
        os.symlink(path.name + ".absent", path)
    else:
        raise ValueError(f"unknown file spec {spec!r}")


class ServerPool:
    """``n`` fork servers; :meth:`run` sends cases to whichever is free."""

    def __init__(self, n: int) -> None:
        env = dict(os.environ)
        env.setdefault("OPENCV_LOG_LEVEL", "ERROR")
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
        env["MPLBACKEND"] = "Agg"
        env["OMNIDEV_MAX_MEMORY"] = "1G"  # the acceptance bound: refuse what would pass it
        env.pop("DISPLAY", None)
        self.procs = [
            subprocess.Popen(
                [sys.executable, "-m", "tests.fuzz.server"],
                cwd=REPO,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                env=env,
            )
            for _ in range(n)
        ]
        self.base_rss_kb = 0
        for p in self.procs:
            assert p.stdout is not None
            hello = json.loads(p.stdout.readline())
            self.base_rss_kb = max(self.base_rss_kb, int(hello["base_rss_kb"]))

    def close(self) -> None:
        for p in self.procs:
            if p.stdin is not None:
                p.stdin.close()
            p.wait(timeout=30)

    def __enter__(self) -> ServerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def run(self, requests: list[dict[str, Any]]) -> list[dict[str, Any]]:
        todo: queue.Queue[tuple[int, dict[str, Any]]] = queue.Queue()
        for i, r in enumerate(requests):
            todo.put((i, r))
        replies: list[dict[str, Any] | None] = [None] * len(requests)

        def work(p: subprocess.Popen[str]) -> None:
            assert p.stdin is not None and p.stdout is not None
            while True:
                try:
                    i, r = todo.get_nowait()
                except queue.Empty:
                    return
                p.stdin.write(json.dumps(r) + "\n")
                p.stdin.flush()
                replies[i] = json.loads(p.stdout.readline())

        threads = [threading.Thread(target=work, args=(p,)) for p in self.procs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        return [r for r in replies if r is not None]


def run_cases(pool: ServerPool, cases: Iterable[Case], workdir: Path) -> list[Outcome]:
    """Run every case in its own folder under ``workdir``; their outcomes in order."""
    cases = list(cases)
    requests = []
    workdir.mkdir(parents=True, exist_ok=True)
    workdir.chmod(0o755)
    for i, case in enumerate(cases):
        folder = workdir / f"case{i:05d}"
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir()
        folder.chmod(0o777)  # writable for the unprivileged user too
        for name, spec in case.files.items():
            _make(folder, name, spec)
        argv = [a.replace("{d}", str(folder)) for a in case.argv]
        requests.append(
            {
                "id": i,
                "argv": argv,
                "cwd": str(folder),
                "timeout": case.timeout,
                "uid": NOBODY if case.as_nobody and os.geteuid() == 0 else None,
                "mem_extra_bytes": ADDRESS_SPACE_EXTRA,
                "env": case.env,
                "log_dir": str(workdir),
            }
        )
    replies = pool.run(requests)
    outcomes = []
    for case, reply in zip(cases, replies, strict=True):
        outcomes.append(
            Outcome(
                case,
                classify(case, reply),
                reply["rc"],
                reply["seconds"],
                reply["maxrss_kb"],
                reply["stderr"],
                reply.get("cpu", 0.0),
            )
        )
    for i in range(len(cases)):
        folder = workdir / f"case{i:05d}"
        for p in folder.rglob("*"):
            if not p.is_symlink():
                p.chmod(p.stat().st_mode | stat.S_IRWXU)
        shutil.rmtree(folder, ignore_errors=True)
    return outcomes


CLASSES = ("clean", "accepted", "silent", "traceback", "hang", "memory", "crash", "unclear")


def summary(outcomes: Sequence[Outcome]) -> str:
    """A table of classes by command (the figure the issue asks for)."""
    by: dict[str, Counter[str]] = defaultdict(Counter)
    for o in outcomes:
        by[o.case.command][o.cls] += 1
    width = max([len(c) for c in by] + [7])
    head = f"{'command':<{width}} {'cases':>6} " + " ".join(f"{c:>9}" for c in CLASSES)
    rows = [head]
    total: Counter[str] = Counter()
    for cmd in sorted(by):
        total.update(by[cmd])
        n = sum(by[cmd].values())
        rows.append(f"{cmd:<{width}} {n:>6} " + " ".join(f"{by[cmd][c]:>9}" for c in CLASSES))
    n = sum(total.values())
    rows.append(f"{'total':<{width}} {n:>6} " + " ".join(f"{total[c]:>9}" for c in CLASSES))
    worst = max((o.maxrss_kb for o in outcomes), default=0) / 1024
    slowest = max((o.seconds for o in outcomes), default=0.0)
    cpu = sum(o.cpu for o in outcomes)
    wall = sum(o.seconds for o in outcomes)
    rows.append(
        f"peak memory of a case {worst:.0f} MiB; slowest case {slowest:.1f} s; cases took "
        f"{wall:.0f} s wall, {cpu:.0f} s CPU in all"
    )
    return "\n".join(rows)
