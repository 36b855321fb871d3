"""The real-kernel tests of tests/vm/, run in ONE booted VM and reported here one by one.

A session fixture boots Debian's kernel under qemu (TCG) with virtme-ng, the
host's filesystem visible read-only inside, and runs tests/vm/run-in-vm.sh,
which loads uinput, vivid, dummy_hcd and the USB HID gadget modules, starts
udev, and runs pytest on tests/vm with a JUnit report in a shared folder.
Every ``test_*`` function of tests/vm/test_*.py (found with ``ast`` at collection
time) becomes ``test_in_vm[file::name]`` here: it passes only when the VM's
JUnit record says that test passed, and fails, with the VM's failure text, when
it failed, was skipped inside, or is missing.

The tests skip (with the reason) only when vng, qemu or the kernel image is
absent, or when the VM did not boot. Set OMNIDEV_VM_KEEP=DIR to keep the VM's
console log, JUnit report and figures in DIR.
"""

from __future__ import annotations

import ast
import glob
import json
import os
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
VM_TESTS = REPO / "tests" / "vm"
VM_TIMEOUT_S = 45 * 60  # TCG is slow; a normal run takes a few minutes
VM_MEMORY = "2G"

pytestmark = pytest.mark.vm


def in_vm_cases() -> list[str]:
    """``file::name`` (or ``file::Class::name``) of every test in tests/vm/test_*.py."""
    cases = []
    for path in sorted(VM_TESTS.glob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in tree.body:
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if node.name.startswith("test"):
                    cases.append(f"{path.name}::{node.name}")
            elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and item.name.startswith("test"):
                        cases.append(f"{path.name}::{node.name}::{item.name}")
    return cases


@dataclass
class VMRun:
    """What one VM boot produced."""

    outdir: Path
    wall_s: float
    console: str
    results: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    problem: str | None = None  # set when the VM ran but pytest inside did not report


def _find_kernel() -> str | None:
    kernels = sorted(glob.glob("/boot/vmlinuz-*-amd64"))
    return kernels[-1] if kernels else None


def _find_vng() -> str | None:
    bindir = str(Path(sys.executable).parent)
    return shutil.which("vng", path=os.pathsep.join([bindir, os.environ.get("PATH", "")]))


def _case_key(classname: str, name: str) -> str:
    """``file::[Class::]name`` of a JUnit record (classname ``tests.vm.test_x[.Class]``)."""
    parts = classname.split(".")
    idx = next((i for i, p in enumerate(parts) if p.startswith("test_")), len(parts) - 1)
    module = parts[idx] + ".py"
    base = name.split("[", 1)[0]  # parametrized tests: one record per parameter
    return "::".join([module, *parts[idx + 1 :], base])


def parse_junit(path: Path) -> dict[str, list[tuple[str, str]]]:
    """case -> [(outcome, text)] with outcome passed/failed/error/skipped."""
    results: dict[str, list[tuple[str, str]]] = {}
    for tc in ET.parse(path).getroot().iter("testcase"):
        key = _case_key(tc.get("classname", ""), tc.get("name", ""))
        outcome, text = "passed", ""
        for tag in ("failure", "error", "skipped"):
            el = tc.find(tag)
            if el is not None:
                outcome = "failed" if tag == "failure" else tag
                text = f"{tc.get('name')}: {el.get('message', '')}\n{el.text or ''}".strip()
                break
        results.setdefault(key, []).append((outcome, text))
    return results


@pytest.fixture(scope="session")
def vm_run(tmp_path_factory: pytest.TempPathFactory, say: Callable[[str], None]) -> VMRun:
    vng = _find_vng()
    if vng is None:
        pytest.skip("VM tests: vng (pip install virtme-ng) is not installed")
    if shutil.which("qemu-system-x86_64") is None:
        pytest.skip("VM tests: qemu-system-x86_64 (apt-get install qemu-system-x86) is absent")
    kernel = _find_kernel()
    if kernel is None:
        pytest.skip("VM tests: no /boot/vmlinuz-*-amd64 (apt-get install linux-image-amd64)")
    keep = os.environ.get("OMNIDEV_VM_KEEP")
    outdir = Path(keep) if keep else tmp_path_factory.mktemp("vm")
    outdir.mkdir(parents=True, exist_ok=True)
    for old in ("booted", "junit.xml", "figures.json", "pytest.log"):
        (outdir / old).unlink(missing_ok=True)
    script = VM_TESTS / "run-in-vm.sh"
    cmd = [
        vng, "--run", kernel, "--user", "root", "--disable-kvm", "--memory", VM_MEMORY,
        "--rwdir", str(outdir), "--exec", f"{script} {outdir} {sys.executable}",
    ]  # fmt: skip
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(vng).parent), env.get("PATH", "")])
    say(f"\nbooting the test VM ({Path(kernel).name}, TCG): {' '.join(cmd)}")
    t0 = time.monotonic()
    try:
        proc = subprocess.run(
            cmd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, errors="replace", timeout=VM_TIMEOUT_S,
        )  # fmt: skip
        console, rc = proc.stdout, proc.returncode
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout
        console = out.decode(errors="replace") if isinstance(out, bytes) else out or ""
        rc = None
    wall = time.monotonic() - t0
    (outdir / "console.log").write_text(console, encoding="utf-8")
    tail = "\n".join(console.splitlines()[-40:])
    if not (outdir / "booted").exists():
        if rc is None:
            pytest.fail(f"the VM did not reach run-in-vm.sh within {VM_TIMEOUT_S} s:\n{tail}")
        pytest.skip(f"VM tests: the VM did not boot (vng exit {rc}): {tail[-600:]}")
    run = VMRun(outdir, wall, console)
    junit = outdir / "junit.xml"
    if rc is None:
        run.problem = f"the VM run timed out after {VM_TIMEOUT_S} s"
    if junit.exists():
        run.results = parse_junit(junit)
    else:
        run.problem = (run.problem or "pytest inside the VM wrote no JUnit report") + f":\n{tail}"
    figures = outdir / "figures.json"
    if figures.exists():
        run.figures = json.loads(figures.read_text())
    counts: dict[str, int] = {}
    for records in run.results.values():
        for outcome, _ in records:
            counts[outcome] = counts.get(outcome, 0) + 1
    say(
        f"test VM: {wall:.0f} s wall time, results {counts}, files in {outdir}\n"
        f"test VM figures: {json.dumps(run.figures, sort_keys=True)}",
    )
    return run


def missing_module(case: str) -> str | None:
    """Why ``case`` cannot run in this VM (a kernel module not built for its kernel), or None.

    v4l2loopback is not part of Debian's kernel package: scripts/install-system-deps.sh
    builds it (v4l2loopback-dkms) for the kernel the VM boots.
    """
    if not case.startswith("test_v4l2_output.py"):
        return None
    kernel = _find_kernel()
    version = Path(kernel).name.removeprefix("vmlinuz-") if kernel else "?"
    if glob.glob(f"/lib/modules/{version}/**/v4l2loopback.ko*", recursive=True):
        return None
    return (
        f"v4l2loopback is not built for kernel {version} (sh scripts/install-system-deps.sh "
        f"installs v4l2loopback-dkms and linux-headers-{version})"
    )


@pytest.mark.parametrize("case", in_vm_cases())
def test_in_vm(vm_run: VMRun, case: str) -> None:
    """The in-VM test ``case`` passed inside the VM."""
    reason = missing_module(case)
    if reason:
        pytest.skip(reason)
    records = vm_run.results.get(case)
    if not records:
        detail = vm_run.problem or "it is not in the VM's JUnit report (not collected?)"
        pytest.fail(f"{case}: no result from the VM: {detail}", pytrace=False)
    bad = [text for outcome, text in records if outcome != "passed"]
    if bad:
        outcomes = sorted({o for o, _ in records if o != "passed"})
        pytest.fail(f"{case} inside the VM: {'/'.join(outcomes)}\n" + "\n".join(bad), pytrace=False)
