"""Atomic output: write to a temporary name beside the target, then put it in place at once.

Rules every output of omnidev follows (files through :func:`atomic_path`,
videos and pipes through the outputs (omnidev.outputs.files, .pipe), folders through
:func:`atomic_dir`):

- The data goes to a temporary ``.NAME.omnidev-PID-XXXX.EXT`` beside the
  target; the target only ever holds a complete file.
- Without ``--force`` the temporary is put in place *create-exclusive* (a hard
  link that fails if the name exists), so of two runs writing one new output
  exactly one succeeds and the other gets a one-line "exists" error; the check
  at the start only makes the common case fail early. With ``--force`` the
  target is replaced (rename).
- On any exception, and on SIGTERM/SIGINT (the CLI turns both into
  exceptions), the temporary is removed. Temporaries that a killed run
  (SIGKILL, power loss) left behind carry its process id: the next run writing
  the same output removes those of processes that no longer exist, and says so.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from omnidev.errors import OutputError

TEMP_TAG = "omnidev-"
"""Temporaries are named ``.STEM.omnidev-PID-RANDOM.SUFFIXES`` (folders too)."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _parent(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def check_output(path: Path, *, force: bool) -> None:
    """Raise :class:`OutputError` if ``path`` exists (and not ``force``), is a folder, or cannot
    be written."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path} is a folder; give a file name for the output")
    if (path.exists() or path.is_symlink()) and not force:
        raise OutputError(f"{path} exists; pass --force to overwrite it")
    parent = _parent(path)
    if not parent.is_dir():
        raise OutputError(f"cannot write {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise OutputError(f"cannot write {path}: directory {parent} is not writable")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def remove_stale_temporaries(path: Path) -> list[Path]:
    """Remove temporaries of ``path`` left by processes that no longer exist; return them.

    Only names of omnidev's own pattern for this very output are touched.
    """
    path = Path(path)
    parent = _parent(path)
    stem, suffix = _split(path)
    pattern = re.compile(
        re.escape(f".{stem}.{TEMP_TAG}") + r"(\d+)-[A-Za-z0-9_]+" + re.escape(suffix) + "$"
    )
    removed: list[Path] = []
    try:
        names = os.listdir(parent)
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        if m is None or _pid_alive(int(m.group(1))):
            continue
        stale = parent / name
        with contextlib.suppress(OSError):
            if stale.is_dir() and not stale.is_symlink():
                shutil.rmtree(stale)
            else:
                stale.unlink()
            removed.append(stale)
            print(
                f"omnidev: removed {stale}, a temporary left by process {m.group(1)} "
                "(killed before it finished)",
                file=sys.stderr,
            )
    return removed


def _split(path: Path) -> tuple[str, str]:
    """(stem, suffix) with every suffix kept together: ``cam.yml.gz`` -> ``cam``, ``.yml.gz``."""
    name = path.name
    stem, dot, rest = name.partition(".")
    if not stem:  # a dot-file: keep its name whole
        return name, ""
    return stem, dot + rest if dot else ""


def make_temporary(path: Path) -> Path:
    """Create an empty temporary file for ``path`` beside it (see the module docstring)."""
    path = Path(path)
    remove_stale_temporaries(path)
    stem, suffix = _split(path)
    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f".{stem}.{TEMP_TAG}{os.getpid()}-", suffix=suffix, dir=_parent(path)
        )
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror}") from None
    os.close(fd)
    return Path(tmp)


def commit_temporary(tmp: Path, path: Path, *, force: bool) -> None:
    """Put the finished temporary ``tmp`` in place as ``path``; remove ``tmp`` whatever happens.

    Without ``force`` this is create-exclusive: if ``path`` appeared meanwhile (another
    run), :class:`OutputError` and ``path`` is left as that run wrote it.
    """
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        if force:
            os.replace(tmp, path)
            return
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise OutputError(
                f"{path} exists (written meanwhile by another run?); pass --force to overwrite it"
            ) from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EMLINK):
                raise OutputError(f"cannot write {path}: {exc.strerror}") from None
            # a file system without hard links (FAT): exclusive creation, then rename
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            except FileExistsError:
                raise OutputError(f"{path} exists; pass --force to overwrite it") from None
            os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


@contextlib.contextmanager
def atomic_path(path: Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a temporary path with the same suffixes; it becomes ``path`` on success.

    On any exception (SIGTERM and Ctrl-C included, see :mod:`omnidev.cli.main`) the
    temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    check_output(path, force=force)
    tmp = make_temporary(path)
    try:
        yield tmp
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
    commit_temporary(tmp, path, force=force)


def check_output_dir(path: Path, *, force: bool) -> None:
    """Raise :class:`OutputError` if folder ``path`` holds files and not ``force``, or is a file."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{path} exists and is not a folder")
    if path.exists() and any(path.iterdir()) and not force:
        raise OutputError(f"{path} exists and is not empty; pass --force to overwrite")


@contextlib.contextmanager
def atomic_dir(path: Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``path``; it replaces ``path`` on success.

    On any exception the temporary folder is removed and ``path`` is untouched.
    """
    path = Path(path)
    check_output_dir(path, force=force)
    remove_stale_temporaries(path)
    _parent(path).mkdir(parents=True, exist_ok=True)
    stem, suffix = _split(path)
    prefix = f".{stem}.{TEMP_TAG}{os.getpid()}-"
    tmp = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=_parent(path)))
    tmp.chmod(0o777 & ~_umask())
    try:
        yield tmp
        if path.exists():
            check_output_dir(path, force=force)  # filled meanwhile by another run
            shutil.rmtree(path)
        tmp.rename(path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
