"""The README's and docs' shell blocks run as written (on the committed fixtures), or say why not.

Every line of a ```sh block in the files of :data:`CHECKED` is one of: an
``omnidev ...`` command, run here from a folder that holds the repository's
fixtures/ and udev/ (as a fresh clone does) and expected to exit 0; a setup line
of :data:`SETUP` (CI runs ``make test``, which runs those); or a line marked
``# needs a camera`` / ``# needs root`` (it is listed, not run). Blocks run in
order, so a later line may use an earlier line's output.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CHECKED = ("README.md", "docs/guide.md")
SETUP = ("make demo", "make test", "make setup", ". .venv/bin/activate")
MARK = re.compile(r"#\s*needs (a camera|root)")


def shell_lines(text: str) -> list[str]:
    """The logical lines (backslash continuations joined) of every ```sh block."""
    lines: list[str] = []
    for block in re.findall(r"^```(?:sh|bash|shell)\n(.*?)^```", text, re.M | re.S):
        joined = block.replace("\\\n", " ")
        lines += [ln.strip() for ln in joined.splitlines() if ln.strip()]
    return lines


def classify(line: str) -> str:
    if line.startswith("#"):
        return "comment"
    if MARK.search(line):
        return "marked"
    if any(line.startswith(s) for s in SETUP):
        return "setup"
    if line.startswith("omnidev "):
        return "run"
    return "unmarked"


@pytest.mark.parametrize("doc", CHECKED)
def test_every_line_runs_or_is_marked(doc):
    lines = shell_lines((REPO / doc).read_text())
    assert lines, f"{doc} has no shell block"
    unmarked = [ln for ln in lines if classify(ln) == "unmarked"]
    assert not unmarked, f"{doc}: lines neither runnable nor marked: {unmarked}"


@pytest.mark.parametrize("doc", CHECKED)
def test_commands_run_as_written(doc, tmp_path):
    for name in ("fixtures", "udev"):
        (tmp_path / name).symlink_to(REPO / name)
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.pop("DISPLAY", None)
    ran = []
    for line in shell_lines((REPO / doc).read_text()):
        if classify(line) != "run":
            continue
        command = line.split(" #", 1)[0]
        shlex.split(command)  # the shell sees the words the docs mean (quoted URIs, ...)
        res = subprocess.run(
            command, shell=True, cwd=tmp_path, env=env, capture_output=True, text=True,
            timeout=600,
        )  # fmt: skip
        assert res.returncode == 0, (
            f"{doc}: `{command}` exited {res.returncode}:\n{res.stderr[-2000:]}"
        )
        ran.append(command)
    print(f"\n{doc}: {len(ran)} commands ran as written")
    assert ran


def test_readme_quotes_its_uris():
    """A URI with & must be quoted, or the shell splits the line (issue 14)."""
    for doc in CHECKED:
        for line in shell_lines((REPO / doc).read_text()):
            for word in re.findall(r"\S*\?\S*&\S*", line.split(" #", 1)[0]):
                assert word[0] in "'\"", f"{doc}: unquoted URI {word}"
