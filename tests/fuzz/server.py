"""A fork server that runs ``omnidev`` command lines in child processes, for the fuzz suite.

It imports omnidev, OpenCV, matplotlib and every plugin once, then for each
request (one JSON object per line on stdin) forks a child that sets a memory
limit, optionally drops to an unprivileged user, redirects its output to files
and calls :func:`omnidev.cli.main.main` exactly as the ``omnidev`` script does.
The parent waits with a timeout (killing a child that hangs) and answers one
JSON line on stdout with the exit status, the child's peak resident memory
(``ru_maxrss`` from ``wait4``) and its standard error.

A forked child is a real separate process: a crash, a hang or a memory blow-up
cannot touch the server or the test run, and starting one costs milliseconds
instead of the ~1 s of a fresh interpreter importing OpenCV.

Request: ``{"id": N, "argv": [...], "cwd": DIR, "timeout": S, "uid": U or null,
"mem_extra_bytes": B (address space allowed above the server's), "stdin": PATH or null}``.
Reply: ``{"id": N, "rc": int or null, "signal": int or null, "timed_out": bool,
"maxrss_kb": int, "seconds": float, "cpu": float (user + system seconds), "stderr": str,
"stdout": str}``.
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import signal
import sys
import time


def _preload() -> None:
    import codecs

    # the children may run as user nobody, who cannot read this interpreter's lazily
    # imported codecs when it lives under /root: load them now
    for name in ("ascii", "utf-8", "utf-8-sig", "latin-1", "utf-16", "idna"):
        codecs.lookup(name)
    import cv2  # noqa: F401
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot

    from omnidev import registry
    from omnidev.cli import main as cli_main

    cli_main.build_parser()
    for group in registry.GROUPS:
        registry.plugins(group)


def _vm_size() -> int:
    """This process's virtual size in bytes (the base the memory limit is added to)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def _child(req: dict, out_path: str, err_path: str) -> None:
    try:
        os.chdir(req["cwd"])
        stdin = req.get("stdin") or os.devnull
        fd = os.open(stdin, os.O_RDONLY)
        os.dup2(fd, 0)
        for target, path in ((1, out_path), (2, err_path)):
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
            os.dup2(fd, target)
            os.close(fd)
        sys.stdin = open(0, closefd=False)  # noqa: SIM115
        sys.stdout = open(1, "w", closefd=False, buffering=1)  # noqa: SIM115
        sys.stderr = open(2, "w", closefd=False, buffering=1)  # noqa: SIM115
        mem = _vm_size() + int(req["mem_extra_bytes"])
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        uid = req.get("uid")
        if uid is not None:
            os.setgroups([])
            os.setgid(uid)
            os.setuid(uid)
        env = req.get("env") or {}
        os.environ.update(env)
        sys.argv = ["omnidev", *req["argv"]]
        from omnidev.cli.main import main

        rc = main(req["argv"])
    except SystemExit as exc:
        code = exc.code
        rc = code if isinstance(code, int) else (0 if code is None else 1)
    except BaseException:
        import traceback

        traceback.print_exc()
        rc = 1
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(rc)


def _tail(path: str, limit: int = 4000) -> str:
    try:
        with open(path, "rb") as fh:
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            fh.seek(max(0, size - limit))
            return fh.read().decode("utf-8", "replace")
    except OSError:
        return ""


def _run(req: dict) -> dict:
    tmp = req["cwd"]
    out_path = os.path.join(req.get("log_dir") or tmp, f".fuzz-{req['id']}.out")
    err_path = os.path.join(req.get("log_dir") or tmp, f".fuzz-{req['id']}.err")
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:
        _child(req, out_path, err_path)
    deadline = t0 + float(req["timeout"])
    timed_out = False
    status = 0
    usage = None
    while True:
        got, status, usage = os.wait4(pid, os.WNOHANG)
        if got == pid:
            break
        if time.monotonic() > deadline:
            timed_out = True
            os.kill(pid, signal.SIGKILL)
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.002)
    seconds = time.monotonic() - t0
    reply = {
        "id": req["id"],
        "rc": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
        "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None,
        "timed_out": timed_out,
        "maxrss_kb": int(usage.ru_maxrss) if usage is not None else 0,
        "seconds": round(seconds, 4),
        "cpu": round(usage.ru_utime + usage.ru_stime, 4) if usage is not None else 0.0,
        "stderr": _tail(err_path),
        "stdout": _tail(out_path, 1000),
    }
    for p in (out_path, err_path):
        with contextlib.suppress(OSError):
            os.unlink(p)
    return reply


def main() -> None:
    _preload()
    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"ready": True, "pid": os.getpid(), "base_rss_kb": base_rss}), flush=True)
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        print(json.dumps(_run(req)), flush=True)


if __name__ == "__main__":
    main()
