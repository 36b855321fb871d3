"""Real-kernel tests: collected only inside the VM that tests/test_kernel_vm.py boots.

On the host these files are not collected (they need /dev/uinput, vivid, a USB
gadget); tests/test_kernel_vm.py boots one VM, runs them there through
run-in-vm.sh, and reports each as its own host test ``test_in_vm[file::name]``.
Inside, OMNIDEV_IN_VM=1 is set and OMNIDEV_VM_OUT names a JSON file for figures.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

IN_VM = bool(os.environ.get("OMNIDEV_IN_VM"))

if not IN_VM:
    collect_ignore_glob = ["*.py"]


@pytest.fixture(scope="session")
def vm_figures() -> Iterator[dict[str, Any]]:
    """A dict of measured figures; merged into $OMNIDEV_VM_OUT (JSON) at the end."""
    figures: dict[str, Any] = {}
    yield figures
    out = os.environ.get("OMNIDEV_VM_OUT")
    if out and figures:
        path = Path(out)
        old = json.loads(path.read_text()) if path.exists() else {}
        path.write_text(json.dumps({**old, **figures}, indent=2, sort_keys=True) + "\n")
