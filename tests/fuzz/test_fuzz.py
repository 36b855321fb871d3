"""The fuzz suite: malformed variants of every input through the real CLI, classified.

Every case runs ``omnidev ...`` in a forked child (tests/fuzz/server.py) with a
timeout and a memory limit and is classed clean error / accepted / silent
acceptance / traceback / hang / memory / crash / unclear (tests/fuzz/harness.py).
The counts by command are printed at the end of the run; any class other than
clean or accepted fails the test and lists the cases.

The normal run holds a fixed sample of the enumerated cases (tests/fuzz/targets.py),
every command in it (:func:`sample`), plus one random mutation per file format drawn
by hypothesis, so that it takes seconds; ``--fuzz-full`` (or ``OMNIDEV_FUZZ_FULL=1``)
runs every enumerated case, every seed and many more random mutations. The full
sweep outside pytest, with the counts by command: ``python -m tests.fuzz.run``.
"""

from __future__ import annotations

import os
import random
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fuzz.harness import GOOD, Case, Outcome, ServerPool, run_cases, summary
from tests.fuzz.mutate import EXTREME, NON_FINITE, NUMBER
from tests.fuzz.seeds import Seeds, make_seeds
from tests.fuzz.targets import (
    FILE_TARGETS,
    config_key_cases,
    file_cases,
    option_cases,
    seed_cases,
)

REPORT: list[Outcome] = []


def full(config: pytest.Config) -> bool:
    return bool(config.getoption("--fuzz-full", False) or os.environ.get("OMNIDEV_FUZZ_FULL"))


@pytest.fixture(scope="module")
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="omnidev-fuzz-") as d:
        os.chmod(d, 0o755)
        yield Path(d)


@pytest.fixture(scope="module")
def seeds(workdir: Path) -> Seeds:
    return make_seeds(workdir / "seeds")


@pytest.fixture(scope="module")
def pool() -> Iterator[ServerPool]:
    with ServerPool(min(2, os.cpu_count() or 1)) as p:
        yield p


SAMPLE_PER_COMMAND = 3
"""Enumerated cases per command (and test) in the normal run."""


def sample(cases: list[Case], config: pytest.Config) -> list[Case]:
    """All of ``cases`` in a full run; else :data:`SAMPLE_PER_COMMAND` of each command,
    spread over its list (so the sample holds different inputs and kinds of damage)."""
    if full(config):
        return cases
    by: dict[str, list[Case]] = {}
    for c in cases:
        by.setdefault(c.command, []).append(c)
    out = []
    for group in by.values():
        step = max(1, len(group) // SAMPLE_PER_COMMAND)
        out += group[::step][:SAMPLE_PER_COMMAND]
    return out


def _check(outcomes: list[Outcome]) -> None:
    REPORT.extend(outcomes)
    bad = [o for o in outcomes if o.cls not in GOOD]
    assert not bad, f"{len(bad)} of {len(outcomes)} cases failed:\n" + "\n".join(
        o.describe() for o in bad[:40]
    )


def test_seeds_are_accepted(pool: ServerPool, seeds: Seeds, workdir: Path, request) -> None:
    """Each file target's unmodified seed runs to exit 0: the suite fuzzes real inputs
    (the normal run: the targets of one command in four)."""
    targets = FILE_TARGETS if full(request.config) else FILE_TARGETS[::4]
    cases = seed_cases(seeds, targets)
    outcomes = run_cases(pool, cases, workdir / "run")
    REPORT.extend(outcomes)
    refused = [o for o in outcomes if o.cls != "accepted"]
    assert not refused, "seeds refused:\n" + "\n".join(o.describe() for o in refused)


def test_malformed_files(pool: ServerPool, seeds: Seeds, workdir: Path, request) -> None:
    _check(run_cases(pool, sample(list(file_cases(seeds)), request.config), workdir / "run"))


def test_bad_options_and_uris(pool: ServerPool, seeds: Seeds, workdir: Path, request) -> None:
    _check(run_cases(pool, sample(list(option_cases(seeds)), request.config), workdir / "run"))


def test_bad_config_keys(pool: ServerPool, seeds: Seeds, workdir: Path, request) -> None:
    cases = list(config_key_cases(seeds))
    if not full(request.config):
        cases = cases[:: max(1, len(cases) // 12)]
    _check(run_cases(pool, cases, workdir / "run"))


_TOKENS = [*NON_FINITE.values(), *EXTREME.values(), b"", b"[", b"{", b'"', b"\n", b",", b"="]


@pytest.mark.parametrize("target", FILE_TARGETS, ids=lambda t: f"{t.command}/{t.what}")
def test_random_mutations(target, pool: ServerPool, seeds: Seeds, workdir: Path, request) -> None:
    """Random edits of the seed (hypothesis): a token replaced, bytes cut or repeated.

    Any outcome but a traceback, hang, memory blow-up, crash or unclear error is allowed.
    """
    seed = seeds.text(target.seed)
    examples = 60 if full(request.config) else 1

    @settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=not full(request.config),
        suppress_health_check=list(HealthCheck),
    )
    @given(st.data())
    def run(data: st.DataObject) -> None:
        edits = data.draw(st.integers(1, 4), label="edits")
        blob = seed
        for _ in range(edits):
            numbers = list(NUMBER.finditer(blob))
            how = data.draw(st.sampled_from(["token", "cut", "repeat", "byte"]))
            if how == "token" and numbers:
                m = numbers[data.draw(st.integers(0, len(numbers) - 1))]
                blob = blob[: m.start()] + data.draw(st.sampled_from(_TOKENS)) + blob[m.end() :]
            elif how == "cut" and blob:
                i = data.draw(st.integers(0, len(blob) - 1))
                j = data.draw(st.integers(i, min(len(blob), i + 64)))
                blob = blob[:i] + blob[j:]
            elif how == "repeat" and blob:
                i = data.draw(st.integers(0, len(blob) - 1))
                blob = blob[:i] + blob[i : i + 32] * data.draw(st.integers(2, 50)) + blob[i:]
            elif blob:
                i = data.draw(st.integers(0, len(blob) - 1))
                blob = blob[:i] + bytes([data.draw(st.integers(0, 255))]) + blob[i + 1 :]
        argv = [
            a.replace("{f}", target.file_name).replace("{s}", str(seeds.root)) for a in target.argv
        ]
        files = {target.file_name: blob}
        if target.seed == "rig.toml":
            files.update(
                {"cam.yml.gz": seeds.text("cam.yml.gz"), "omni.png": seeds.text("omni.png")}
            )
        case = Case(target.command, f"{target.what}: random edits", argv, files, expect="any")
        _check(run_cases(pool, [case], workdir / "run"))

    random.seed(0)
    run()


def pytest_terminal_summary_text() -> str:
    return summary(REPORT) if REPORT else ""


def test_matrix_cut_before_its_cols(pool: ServerPool, seeds: Seeds, workdir: Path) -> None:
    """An opencv-matrix without ``cols`` (a random edit of fuzz seed 49): cv2's
    ``FileNode.mat()`` on it corrupted the heap of the forked child reading it, which
    died in ``free()`` (whether it dies depends on the heap's layout: in this test's
    server it did not). Now the header is checked before OpenCV reads the matrix, and
    the error says what is missing; so is a data count that does not fit the header."""
    seed = seeds.text("cam_unified.yml").decode()
    head, rest = seed.split("radial_coeffs: !!opencv-matrix\n", 1)
    rows, cols, rest = rest.split("\n", 2)
    assert rows.strip() == "rows: 1" and cols.strip() == "cols: 2", (rows, cols)
    argv = ["unwarp", f"{seeds.root}/omni.png", "--camera", "in.yml", "--view", "panorama:64x16"]
    cases = [
        Case(
            "unwarp",
            f"pano-table: radial_coeffs {what}",
            [*argv, "-o", "out.png"],
            {"in.yml": head.encode() + b"radial_coeffs: !!opencv-matrix\n" + text + rest.encode()},
        )
        for what, text in (
            ("without cols", b"   rows:2\n"),
            ("with 3 values for 1 x 2", b"   rows: 1\n   cols: 3\n"),
            # FileNode.keys() would raise UnicodeDecodeError on this key (fuzz seeds 49, 50)
            ("with a key name that is not UTF-8", b"   rows: 1\n   \xd1: 2\n"),
        )
    ]
    outcomes = run_cases(pool, cases, workdir / "run")
    REPORT.extend(outcomes)
    needles = ("(no cols)", "holds 2 values, not 1 x 3 of d", "(no cols)")
    for o, needle in zip(outcomes, needles, strict=True):
        assert o.cls == "clean", o.describe()
        assert "in.yml: matrix key 'radial_coeffs' is incomplete" in o.stderr, o.stderr
        assert needle in o.stderr, o.stderr
