"""The README's and docs' shell blocks run as written (on the committed fixtures), or say why not.

Every logical line of a ```sh block in README.md and docs/*.md is one of:

- an ``omnidev ...`` command (or ``.venv/bin/omnidev ...``), run here from a
  folder that holds the repository's fixtures/, udev/ and scripts/ (as a fresh
  clone does) and expected to exit 0;
- a ``cat > FILE <<'EOF'`` here-document writing a file there, or a
  ``python - <<'EOF'`` one (run too);
- a setup line of :data:`SETUP` (CI runs ``make test``, which runs those);
- a line marked ``# needs a camera`` / ``# needs root`` / ``# takes minutes`` (a full
  evaluation; the test suite runs a small sample of those) ... (:data:`MARK`), or
  in a block whose first line is such a comment: listed, not run;
- a comment.

Blocks run in order, so a later line may use an earlier line's output.
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
CHECKED = ("README.md", *sorted(f"docs/{p.name}" for p in (REPO / "docs").glob("*.md")))
SETUP = ("make demo", "make test", "make setup", ". .venv/bin/activate")
MARK = re.compile(
    r"#\s*(needs (a camera|root|a display|the system install|a USB gadget|the \S+ plugin"
    r"|a cluster|your archive)|takes minutes)"
)
"""Why a line is not run: the hardware, privileges or installed files it needs."""
HEREDOC = re.compile(r"^(?:cat > (\S+)|python3? -) <<'?(\w+)'?\s*$")
PREFIX = ".venv/bin/omnidev "


def shell_blocks(text: str) -> list[list[str]]:
    """The logical lines of every ```sh block: backslash continuations joined, a
    here-document kept with its command as one line."""
    blocks = []
    for block in re.findall(r"^```(?:sh|bash|shell)\n(.*?)^```", text, re.M | re.S):
        raw = block.replace("\\\n", " ").splitlines()
        lines: list[str] = []
        i = 0
        while i < len(raw):
            line = raw[i].strip()
            m = HEREDOC.match(line)
            if m:
                end = next(j for j in range(i + 1, len(raw)) if raw[j].strip() == m.group(2))
                lines.append("\n".join([line, *raw[i + 1 : end], m.group(2)]))
                i = end + 1
                continue
            if line:
                lines.append(line)
            i += 1
        blocks.append(lines)
    return blocks


def shell_lines(text: str) -> list[str]:
    return [ln for block in shell_blocks(text) for ln in block]


def classify(line: str, block_marked: bool = False) -> str:
    first = line.splitlines()[0]
    if block_marked:
        return "marked"
    if first.startswith("#"):
        return "comment"
    if MARK.search(first):
        return "marked"
    if any(first.startswith(s) for s in SETUP):
        return "setup"
    if first.startswith(("omnidev ", PREFIX)):
        return "run"
    m = HEREDOC.match(first)
    if m and not (m.group(1) or "").startswith("/"):
        return "run"
    return "unmarked"


def classified(doc: str) -> list[tuple[str, str]]:
    out = []
    for block in shell_blocks((REPO / doc).read_text()):
        marked = bool(block) and block[0].startswith("#") and bool(MARK.search(block[0]))
        out += [(classify(ln, marked), ln) for ln in block]
    return out


def test_readme_and_guide_have_commands():
    for doc in ("README.md", "docs/guide.md"):
        assert any(c == "run" for c, _ in classified(doc)), doc


@pytest.mark.parametrize("doc", CHECKED)
def test_every_line_runs_or_is_marked(doc):
    unmarked = [ln for c, ln in classified(doc) if c == "unmarked"]
    assert not unmarked, f"{doc}: lines neither runnable nor marked: {unmarked}"


RUNNABLE = [d for d in CHECKED if any(c == "run" for c, _ in classified(d))]


@pytest.mark.parametrize("doc", RUNNABLE)
def test_commands_run_as_written(doc, tmp_path):
    for name in ("fixtures", "udev", "scripts"):
        (tmp_path / name).symlink_to(REPO / name)
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.pop("DISPLAY", None)
    ran = []
    for c, line in classified(doc):
        if c != "run":
            continue
        command = line if "\n" in line else line.split(" #", 1)[0]
        if command.startswith(PREFIX):
            command = "omnidev " + command[len(PREFIX) :]
        if "\n" not in command:
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


def test_docs_quote_their_uris():
    """A URI with & must be quoted, or the shell splits the line (issue 14)."""
    for doc in CHECKED:
        for _c, line in classified(doc):
            if "\n" in line:
                continue
            for word in re.findall(r"\S*\?\S*&\S*", line.split(" #", 1)[0]):
                assert word[0] in "'\"", f"{doc}: unquoted URI {word}"


def test_no_control_socket_in_tmp():
    """Another user can take a socket name in /tmp first (issue 14): the docs do not use one."""
    for doc in CHECKED:
        text = (REPO / doc).read_text()
        assert not re.search(r"/tmp/\S*\.sock", text), f"{doc}: a control socket in /tmp"
