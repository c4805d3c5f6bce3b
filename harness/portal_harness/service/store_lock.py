"""One server per results folder: `serve` takes an exclusive flock on
RESULTS/serve.lock before it touches anything (the token file, the queue's
recovery of running experiments, the workers, the port). A second server
on the same folder finds it held, names the lock and the pid written in it,
and leaves without changing anything.

The lock lives as long as the open file: the server's process (its
descriptor is not inherited by the workers it starts). A killed server
releases it with its process, so a restart takes it again at once."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

from portal_harness.core.errors import HarnessError

LOCK_NAME = "serve.lock"


class StoreLocked(HarnessError):
    """Another server holds the results folder's lock."""

    exit_status = 2


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", errors="replace").strip()
    except OSError:
        return "unknown"
    return text if text.isdigit() else "unknown"


def lock_store(results: Path) -> int:
    """Takes the lock of `results` (made if missing) for this process; returns
    the descriptor to keep open. StoreLocked if another process holds it."""
    results.mkdir(parents=True, exist_ok=True)
    path = results / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = _holder(fd)
        os.close(fd)
        raise StoreLocked(
            f"another portal-harness serve (pid {pid}) holds the lock {path} on the results folder "
            f"{results}: one server per results folder; nothing was changed"
        ) from None
    except BaseException:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return fd
