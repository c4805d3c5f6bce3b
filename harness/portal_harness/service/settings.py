"""The service's settings, fixed at start (`portal-harness serve` options)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from portal_harness.core.paths import ResultsLayout
from portal_harness.experiment.limits import Limits

DEFAULT_MAX_BODY_BYTES = 256 * 1024
DEFAULT_PORT = 8750
SPOOL_NAME = "service"  # RESULTS/service/: submitted files, sweep logs, the made token


@dataclass(frozen=True)
class ServiceSettings:
    layout: ResultsLayout
    renderer: str  # absolute path of the renderer binary
    roots: tuple[Path, ...]  # the folders submitted experiments may name files in (resolved)
    token: str | None  # bearer token of writes (and of every request off loopback)
    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    scheduler: str | None = None  # a Dask scheduler address, or the local pool
    jobs: int | None = None  # concurrent renders of one sweep (default: cores // threads)
    parallel: int = 1  # sweeps run at once
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES
    poll_s: float = 0.25  # how often the dispatcher and the event streams look
    figures: bool = True  # draw the figures (and the viewer's bundle) after each sweep
    nice: int = 0  # niceness of the sweeps' processes (workers, renders), over the API's
    limits: Limits = field(default_factory=Limits)  # on one submission's work (experiment/limits.py)

    @property
    def spool(self) -> Path:
        """Submitted experiment files and their sweep logs, one folder per id."""
        return self.layout.root / SPOOL_NAME

    def submission_dir(self, experiment_id: str) -> Path:
        return self.spool / experiment_id

    @property
    def every_request_needs_token(self) -> bool:
        from portal_harness.service.security import is_loopback

        return not is_loopback(self.host)
