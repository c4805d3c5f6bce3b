"""The real `portal-harness serve`, started as a process on a free port and
driven over HTTP (urllib), for the service's process-level tests."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

TOKEN = "server-test-token"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Service:
    def __init__(self, results: Path, root: Path, renderer: Path, port: int, token: str | None = TOKEN) -> None:
        self.results, self.root, self.renderer, self.port, self.token = results, root, renderer, port, token
        self.process: subprocess.Popen[bytes] | None = None

    def command(self) -> list[str]:
        command = [sys.executable, "-m", "portal_harness", "serve", "--port", str(self.port)]
        command += ["--results", str(self.results), "--renderer", str(self.renderer), "--root", str(self.root)]
        return [*command, "--no-figures"]

    def env(self) -> dict[str, str]:
        """The environment of the service: the token in $PORTAL_HARNESS_TOKEN, or none (then it makes one)."""
        env = {k: v for k, v in os.environ.items() if k != "PORTAL_HARNESS_TOKEN"}
        return env if self.token is None else {**env, "PORTAL_HARNESS_TOKEN": self.token}

    def start(self) -> None:
        self.process = subprocess.Popen(
            self.command(), env=self.env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            try:
                self.get("/api/experiments")
                return
            except (urllib.error.URLError, ConnectionError):
                time.sleep(0.1)
        raise AssertionError("the service did not answer within 30 s")

    def request(self, method: str, path: str, body: bytes | None = None, token: str | None = None) -> Any:
        headers = {"Content-Type": "application/yaml"}
        if token:
            headers["Authorization"] = f"Bearer {token}"
        req = urllib.request.Request(f"http://127.0.0.1:{self.port}{path}", body, headers, method=method)
        with urllib.request.urlopen(req, timeout=30) as r:
            return json.loads(r.read())

    def get(self, path: str) -> Any:
        return self.request("GET", path)

    def kill(self) -> None:
        assert self.process is not None
        self.process.send_signal(signal.SIGKILL)
        self.process.wait()

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
