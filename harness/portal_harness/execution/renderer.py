"""Running the renderer binary: its version, and one render as a subprocess
whose JSON-lines stdout is followed event by event (renderer contract)."""

from __future__ import annotations

import ctypes
import json
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from portal_harness.core.errors import RendererError

EventCallback = Callable[[dict[str, Any]], None]

# Exit statuses of the renderer contract.
EXIT_OK = 0
EXIT_RUNTIME = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 3


def parse_events(lines: Iterable[str | bytes]) -> list[dict[str, Any]]:
    """The events of a stored JSON-lines stream (a run's events.jsonl): each
    line that is a JSON object; anything else (a line cut by a tail read or
    by a killed render) is skipped."""
    out: list[dict[str, Any]] = []
    for line in lines:
        try:
            event = json.loads(line)
        except ValueError:
            continue
        if isinstance(event, dict):
            out.append(event)
    return out


@lru_cache(maxsize=16)
def renderer_version(path: str) -> str:
    """The version the renderer reports for `--version` (its last word)."""
    if not Path(path).is_file():
        raise RendererError(f"renderer not found at {path} (build it with `make`, or pass --renderer)")
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30, check=False)
    except OSError as e:
        raise RendererError(f"cannot run renderer {path}: {e.strerror}") from None
    except subprocess.TimeoutExpired:
        raise RendererError(f"renderer {path} did not answer --version within 30 s") from None
    words = out.stdout.split()
    if out.returncode != 0 or not words:
        raise RendererError(f"renderer {path} --version failed (exit {out.returncode}): {out.stderr.strip()[:200]}")
    return words[-1]


def _die_with_parent() -> Callable[[], None] | None:
    """A preexec function that asks Linux to SIGTERM the renderer when the
    harness (the forking thread) dies, so that a killed sweep leaves no
    orphan renders behind; the renderer then writes final.exr and exits 3.
    The libc function is looked up here, before the fork."""
    try:
        prctl = ctypes.CDLL("libc.so.6", use_errno=True).prctl
    except OSError:  # pragma: no cover - not glibc
        return None
    pr_set_pdeathsig = 1
    term = int(signal.SIGTERM)

    def preexec() -> None:
        prctl(pr_set_pdeathsig, term, 0, 0, 0)

    return preexec


@dataclass
class RenderResult:
    exit_status: int
    signal_name: str | None
    wall_s: float
    events: list[dict[str, Any]] = field(default_factory=list)
    malformed_lines: list[str] = field(default_factory=list)
    timed_out: bool = False


def render(
    command: list[str],
    events_path: Path,
    stderr_path: Path,
    on_event: EventCallback | None = None,
    timeout_s: float | None = None,
) -> RenderResult:
    """Runs one render to completion. stdout lines go to `events_path` and,
    parsed, to `on_event`; stderr goes to `stderr_path`. A render still running
    after `timeout_s` wall seconds gets SIGTERM, then SIGKILL 10 s later."""
    start = time.monotonic()
    events: list[dict[str, Any]] = []
    malformed: list[str] = []
    timed_out = threading.Event()
    with open(stderr_path, "wb") as err_file, open(events_path, "w") as events_file:
        try:
            proc = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=err_file,
                text=True,
                bufsize=1,
                preexec_fn=_die_with_parent(),
            )
        except OSError as e:
            err_file.write(f"cannot start {command[0]}: {e.strerror}\n".encode())
            return RenderResult(exit_status=127, signal_name=None, wall_s=0.0)

        def expire() -> None:
            timed_out.set()
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()

        timer = threading.Timer(timeout_s, expire) if timeout_s else None
        if timer:
            timer.daemon = True
            timer.start()
        try:
            assert proc.stdout is not None
            for line in proc.stdout:
                events_file.write(line)
                events_file.flush()
                text = line.strip()
                if not text:
                    continue
                try:
                    event = json.loads(text)
                except json.JSONDecodeError:
                    malformed.append(text[:200])
                    continue
                if not isinstance(event, dict):
                    malformed.append(text[:200])
                    continue
                events.append(event)
                if on_event is not None:
                    on_event(event)
            code = proc.wait()
        except BaseException:
            # Interrupted harness: stop the render the way the contract allows
            # (SIGTERM writes final.exr and exits 3), then re-raise.
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            raise
        finally:
            if timer:
                timer.cancel()
    signal_name = None
    if code < 0:
        try:
            signal_name = signal.Signals(-code).name
        except ValueError:
            signal_name = f"signal {-code}"
    return RenderResult(
        exit_status=code,
        signal_name=signal_name,
        wall_s=time.monotonic() - start,
        events=events,
        malformed_lines=malformed,
        timed_out=timed_out.is_set(),
    )
