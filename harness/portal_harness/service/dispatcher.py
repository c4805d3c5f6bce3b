"""Starts queued experiments as worker processes (worker.py), each in its
own process group, at most `parallel` at once; notices their end; cancels
by signalling the group (SIGTERM: the renderers write their final image
and exit, nothing is installed half-written; SIGKILL after a grace period).

At start, experiments a previous service left `running` are queued again
(their worker died with it): their sweep resumes where the store says.
One thread does all of this, so worker processes are forked by a thread
that lives as long as the service (the parent-death signal follows the
forking thread).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass

from portal_harness.service import queue as q
from portal_harness.service.settings import ServiceSettings
from portal_harness.service.worker import LOG_NAME

CANCEL_GRACE_S = 5.0


@dataclass
class _Worker:
    experiment_id: str
    process: subprocess.Popen[bytes]
    cancel_sent: float | None = None


def _is_our_worker(pid: int, experiment_id: str) -> bool:
    """True if `pid` is a worker of this experiment (not a reused pid)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
    except OSError:
        return False
    return b"portal_harness.service.worker" in argv and experiment_id.encode() in argv


class Dispatcher:
    def __init__(self, settings: ServiceSettings, queue: q.Queue) -> None:
        self.settings = settings
        self.queue = queue
        self._workers: dict[str, _Worker] = {}
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._cancels: set[str] = set()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, name="dispatcher", daemon=True)

    def start(self) -> None:
        self.recover()
        self._thread.start()

    def stop(self) -> None:
        """Stops dispatching and the running workers (their experiments stay
        `running` in the queue, and are resumed at the next start)."""
        self._stop.set()
        self._wake.set()
        self._thread.join(timeout=10)
        for w in list(self._workers.values()):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(w.process.pid, signal.SIGKILL)
            w.process.wait()

    def wake(self) -> None:
        self._wake.set()

    def cancel(self, experiment_id: str) -> None:
        """Asks the dispatcher thread to stop the experiment's worker."""
        with self._lock:
            self._cancels.add(experiment_id)
        self._wake.set()

    def recover(self) -> None:
        """Experiments left running by a service that died: their worker (if
        any survived) is killed, and they are queued again, to resume."""
        for row in self.queue.with_status(q.RUNNING):
            pid = row["pid"]
            if pid and _is_our_worker(int(pid), str(row["id"])):
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(int(pid), signal.SIGKILL)
            if row["cancel_requested"]:
                self.queue.finish(str(row["id"]), q.CANCELLED, "cancelled")
            else:
                self.queue.requeue(str(row["id"]))

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self._tick()
            except Exception as e:  # the loop must outlive a bad row or a full disk
                print(f"portal-harness serve: dispatcher: {type(e).__name__}: {e}", file=sys.stderr)
            self._wake.wait(self.settings.poll_s)
            self._wake.clear()

    def _tick(self) -> None:
        with self._lock:
            cancels, self._cancels = self._cancels, set()
        for experiment_id in cancels:
            w = self._workers.get(experiment_id)
            if w is not None and w.cancel_sent is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(w.process.pid, signal.SIGTERM)
                w.cancel_sent = time.monotonic()
        for experiment_id, w in list(self._workers.items()):
            code = w.process.poll()
            if code is None:
                if w.cancel_sent is not None and time.monotonic() - w.cancel_sent > CANCEL_GRACE_S:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(w.process.pid, signal.SIGKILL)
                continue
            # The worker is gone; what it left in its group (a render) goes too.
            with contextlib.suppress(ProcessLookupError):
                os.killpg(w.process.pid, signal.SIGKILL)
            del self._workers[experiment_id]
            row = self.queue.get(experiment_id)
            if row is not None and row["cancel_requested"]:
                self.queue.finish(experiment_id, q.CANCELLED, "cancelled", only_if=q.RUNNING)
            else:
                self.queue.finish(
                    experiment_id, q.FAILED, f"the worker exited with status {code} (see {LOG_NAME})", only_if=q.RUNNING
                )
        while len(self._workers) < self.settings.parallel and not self._stop.is_set():
            row = self.queue.next_queued()
            if row is None:
                break
            self._start(row)

    def _start(self, row: dict[str, object]) -> None:
        experiment_id = str(row["id"])
        folder = self.settings.submission_dir(experiment_id)
        folder.mkdir(parents=True, exist_ok=True)
        command = [
            sys.executable,
            "-m",
            "portal_harness.service.worker",
            "--id",
            experiment_id,
            "--results",
            str(self.settings.layout.root),
            "--renderer",
            self.settings.renderer,
            "--parent",
            str(os.getpid()),
        ]
        for root in self.settings.roots:
            command += ["--root", str(root)]
        if self.settings.scheduler:
            command += ["--scheduler", self.settings.scheduler]
        if self.settings.nice:
            command += ["--nice", str(self.settings.nice)]
        if not self.settings.figures:
            command.append("--no-figures")
        if self.settings.jobs:
            command += ["--jobs", str(self.settings.jobs)]
        # Running before the worker exists: the worker records its end only over `running`.
        self.queue.mark_running(experiment_id, None)
        with open(folder / LOG_NAME, "ab") as log:
            process = subprocess.Popen(
                command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
            )
        self.queue.set_pid(experiment_id, process.pid)
        self._workers[experiment_id] = _Worker(experiment_id, process)

    def running(self) -> list[str]:
        return list(self._workers)
