#!/usr/bin/env python3
"""Load benchmark of `portal-harness serve` (issue 16): N concurrent clients
(default 50) poll an experiment and follow its event stream while its sweep
renders; prints and writes the p50/p99 latency of their requests, the
failed requests, and the render slowdown: the samples per second of the
sweep's renders with the clients against without them, measured in the
same run (one sweep before the clients, one with them, one after; the
baseline is the mean of before and after, so a drift of the machine's load
shows as their difference, which is reported too).

    .venv/bin/python tools/service_load/service_load.py [--clients 50] [--out results/bench/service_load.json]

It starts the service itself (real renderer, a fresh results folder in a
temporary directory, the repository's configs/ as the root). The clients
run in this process (asyncio + httpx) on the same machine: their own CPU
cost is part of the slowdown, as it would be for users on the render host.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import yaml

REPO = Path(__file__).resolve().parents[2]
TOKEN = "service-load-token"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def experiment(name: str, seed: int, run_time_s: float, size: int) -> str:
    return yaml.safe_dump(
        {
            "name": name,
            "scene": "scenes/lampshade.yaml",
            "integrator": "direct",
            "strategies": ["light", "antishadow"],
            "sweep": {"params.s_L": [0.15, 0.6]},
            "fixed": {"params.s_P": 0.3, "film.width": size, "film.height": size},
            "budget": {"time_s": run_time_s, "threads": 1, "seed": seed, "replicates": 2, "snapshots": {"every": 0.25}},
            # Shared by the three sweeps (same key): rendered once, before the first.
            "reference": {"strategy": "light", "spp": 512, "seed": 7, "noise_ratio": 0.9, "max_time_s": 4},
        }
    )


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    i = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[i]


class Load:
    """The clients' record: request latencies (s), failures, events received."""

    def __init__(self) -> None:
        self.latencies: list[float] = []
        self.failures: list[str] = []
        self.events = 0
        self.streams_ended = 0


class RawConnection:
    """One simulated user's keep-alive HTTP/1.1 connection, on bare asyncio streams. The users are
    simulated in this one process on the service's 2 cores, so they must cost little: with one shared
    httpx pool of 100 connections a burst of 50 requests spent ~0.5 s queueing in httpx, and those
    were most of the latencies measured while the server answered in 15-30 ms (p95)."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None

    async def _open(self) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
        if self.reader is None or self.writer is None or self.writer.is_closing():
            self.reader, self.writer = await asyncio.open_connection(self.host, self.port)
        return self.reader, self.writer

    async def head(self, path: str) -> tuple[int, dict[str, str], asyncio.StreamReader]:
        """Sends GET `path`; returns the status, the headers (lower-case names) and the reader at the body."""
        reader, writer = await self._open()
        writer.write(f"GET {path} HTTP/1.1\r\nHost: {self.host}\r\nAccept: */*\r\n\r\n".encode())
        await writer.drain()
        status_line = await reader.readline()
        if not status_line:
            raise ConnectionError("connection closed before the status line")
        status = int(status_line.split()[1])
        headers: dict[str, str] = {}
        while (line := await reader.readline()) not in (b"\r\n", b""):
            name, _, value = line.decode("latin-1").partition(":")
            headers[name.strip().lower()] = value.strip()
        return status, headers, reader

    async def get(self, path: str) -> tuple[int, bytes]:
        """GET `path` with a Content-Length body (every non-streaming answer of the service)."""
        status, headers, reader = await self.head(path)
        body = await reader.readexactly(int(headers.get("content-length", "0")))
        if headers.get("connection", "").lower() == "close":
            await self.close()
        return status, body

    async def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            with contextlib.suppress(OSError):
                await self.writer.wait_closed()
        self.reader = self.writer = None


async def poller(host: str, port: int, experiment_id: str, load: Load, stop: asyncio.Event, period: float) -> None:
    paths = [f"/api/experiments/{experiment_id}", "/api/experiments"]
    conn = RawConnection(host, port)
    i = 0
    try:
        while not stop.is_set():
            path = paths[i % len(paths)]
            i += 1
            t0 = time.perf_counter()
            try:
                status, body = await conn.get(path)
                if status != 200:
                    load.failures.append(f"GET {path}: {status}")
                else:
                    json.loads(body)  # a complete JSON answer is part of a successful read
            except (OSError, ValueError, asyncio.IncompleteReadError) as e:
                load.failures.append(f"GET {path}: {type(e).__name__}: {e}")
                await conn.close()
            load.latencies.append(time.perf_counter() - t0)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), timeout=period)
    finally:
        await conn.close()


async def follower(host: str, port: int, experiment_id: str, load: Load) -> None:
    """Follows the experiment's event stream to its `end` event (the chunked framing's size lines are
    hex numbers, so counting the lines that start with `event: ` counts the events)."""
    conn = RawConnection(host, port)
    try:
        status, _, reader = await conn.head(f"/api/experiments/{experiment_id}/events")
        if status != 200:
            load.failures.append(f"events: {status}")
            return
        while line := await reader.readline():
            if line.startswith(b"event: "):
                load.events += 1
                if line.rstrip() == b"event: end":
                    load.streams_ended += 1
                    return
        load.failures.append("events: the stream closed before its end event")
    except (OSError, ValueError) as e:
        load.failures.append(f"events: {type(e).__name__}: {e}")
    finally:
        await conn.close()


async def wait_done(client: httpx.AsyncClient, experiment_id: str, timeout_s: float = 600) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        view: dict[str, Any] = (await client.get(f"/api/experiments/{experiment_id}")).json()
        if view["status"] in ("done", "failed", "cancelled"):
            return view
        await asyncio.sleep(0.5)
    raise TimeoutError(f"experiment {experiment_id} did not finish in {timeout_s} s")


async def submit(client: httpx.AsyncClient, text: str) -> str:
    r = await client.post(
        "/api/experiments",
        content=text,
        headers={"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/yaml"},
    )
    r.raise_for_status()
    return str(r.json()["id"])


def cpu_s(pid: int) -> float:
    """User + system CPU time of a process (not its children), from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    ticks = int(fields[11]) + int(fields[12])
    return ticks / os.sysconf("SC_CLK_TCK")


def samples_per_s(results: Path, view: dict[str, Any], pixels: int) -> list[float]:
    """Samples per second of render time of each run of a finished sweep (its manifest's final image)."""
    out = []
    for run in view["runs"]:
        if run["role"] != "run" or run["status"] != "done":
            continue
        manifest = json.loads((results / "runs" / run["key"] / "manifest.json").read_text())
        final = manifest["final"]
        out.append(final["spp"] * pixels / final["time_s"])
    return out


async def measure(
    base: str, results: Path, clients: int, run_time_s: float, size: int, period: float, server_pid: int
) -> dict[str, Any]:
    limits = httpx.Limits(max_connections=4 * clients + 8, max_keepalive_connections=4 * clients)
    async with httpx.AsyncClient(base_url=base, timeout=30, limits=limits) as client:
        phases: dict[str, dict[str, Any]] = {}
        for phase, seed in (("before", 1), ("with_clients", 101), ("after", 201)):
            experiment_id = await submit(client, experiment(f"load_{phase}", seed, run_time_s, size))
            load = Load()
            stop = asyncio.Event()
            tasks = []
            t0 = time.monotonic()
            cpu0 = cpu_s(server_pid)
            own0 = time.process_time()
            if phase == "with_clients":
                # Wait until the sweep renders its runs (references are shared and made before).
                while True:
                    view = (await client.get(f"/api/experiments/{experiment_id}")).json()
                    if view["status"] == "running":
                        break
                    await asyncio.sleep(0.1)
                url = httpx.URL(base)
                host, port = str(url.host), int(url.port or 80)
                for _ in range(clients):
                    tasks.append(asyncio.create_task(poller(host, port, experiment_id, load, stop, period)))
                    tasks.append(asyncio.create_task(follower(host, port, experiment_id, load)))
            view = await wait_done(client, experiment_id)
            wall = time.monotonic() - t0
            server_cpu = cpu_s(server_pid) - cpu0
            client_cpu = time.process_time() - own0
            stop.set()
            await asyncio.gather(*tasks)
            rates = samples_per_s(results, view, size * size)
            phases[phase] = {
                "status": view["status"],
                "wall_s": round(wall, 2),
                "service_cpu_s": round(server_cpu, 2),  # the API process only (workers are its children)
                "clients_cpu_s": round(client_cpu, 2),  # this process: the simulated clients
                "runs": len(rates),
                "samples_per_s_mean": statistics.fmean(rates) if rates else None,
                "samples_per_s": [round(r) for r in rates],
            }
            if phase == "with_clients":
                ms = [1000 * x for x in load.latencies]
                phases[phase]["clients"] = {
                    "clients": clients,
                    "poll_period_s": period,
                    "requests": len(ms),
                    "failed_requests": len(load.failures),
                    "failures": load.failures[:10],
                    "latency_ms_p50": round(percentile(ms, 50), 2),
                    "latency_ms_p95": round(percentile(ms, 95), 2),
                    "latency_ms_p99": round(percentile(ms, 99), 2),
                    "latency_ms_max": round(max(ms), 2) if ms else None,
                    "event_streams": clients,
                    "event_streams_ended_cleanly": load.streams_ended,
                    "events_received": load.events,
                }
        return phases


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--clients", type=int, default=50)
    p.add_argument("--period", type=float, default=1.0, help="seconds between one client's polls")
    p.add_argument("--run-time", type=float, default=2.0, help="render time of each run (s)")
    p.add_argument("--size", type=int, default=64, help="image width and height (pixels)")
    p.add_argument("--renderer", type=Path, default=REPO / "renderer" / "build" / "render")
    p.add_argument("--nice", type=int, default=None, help="the service's --nice (default: the service's own)")
    p.add_argument("--out", type=Path, default=REPO / "results" / "bench" / "service_load.json")
    args = p.parse_args()
    port = free_port()
    with tempfile.TemporaryDirectory(prefix="service-load-") as tmp:
        results = Path(tmp) / "results"
        command = [sys.executable, "-m", "portal_harness", "serve", "--port", str(port), "--results", str(results)]
        command += ["--renderer", str(args.renderer), "--root", str(REPO / "configs"), "--no-figures"]
        if args.nice is not None:
            command += ["--nice", str(args.nice)]
        env = {**os.environ, "PORTAL_HARNESS_TOKEN": TOKEN}
        load_before = os.getloadavg()
        server = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            base = f"http://127.0.0.1:{port}"
            deadline = time.monotonic() + 30
            while True:
                try:
                    httpx.get(base + "/api/experiments", timeout=2)
                    break
                except httpx.HTTPError:
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.2)
            phases = asyncio.run(
                measure(base, results, args.clients, args.run_time, args.size, args.period, server.pid)
            )
        finally:
            server.send_signal(signal.SIGTERM)
            try:
                server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
    before, after = phases["before"]["samples_per_s_mean"], phases["after"]["samples_per_s_mean"]
    loaded = phases["with_clients"]["samples_per_s_mean"]
    baseline = (before + after) / 2
    report = {
        "what": "portal-harness serve under N clients polling (GET experiment / list) and following its events "
        "while its sweep renders (8 runs, 2 concurrent, 1 thread each); slowdown = 1 - samples/s with the "
        "clients / mean samples/s of the sweeps before and after",
        "cores": os.cpu_count(),
        "load_average_at_start": [round(x, 2) for x in load_before],
        "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
        "image": f"{args.size}x{args.size}",
        "run_time_s": args.run_time,
        "sweep_niceness": "default of serve" if args.nice is None else args.nice,
        "date": time.strftime("%Y-%m-%d"),
        **phases["with_clients"]["clients"],
        "samples_per_s_without_clients": round(baseline),
        "samples_per_s_with_clients": round(loaded),
        "render_slowdown": round(1 - loaded / baseline, 4),
        "baseline_drift": round((after - before) / baseline, 4),
        "phases": phases,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    c = phases["with_clients"]["clients"]
    print(
        f"{c['clients']} clients: {c['requests']} requests, {c['failed_requests']} failed, "
        f"p50 {c['latency_ms_p50']} ms, p95 {c['latency_ms_p95']} ms, p99 {c['latency_ms_p99']} ms; "
        f"{c['event_streams_ended_cleanly']}/"
        f"{c['event_streams']} event streams followed to their end ({c['events_received']} events)"
    )
    print(
        f"render samples/s: {baseline:.4g} without clients (before {before:.4g}, after {after:.4g}), "
        f"{loaded:.4g} with: slowdown {100 * (1 - loaded / baseline):.1f}%"
    )
    print(f"written: {args.out}")
    return 0 if c["failed_requests"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
