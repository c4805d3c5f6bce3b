"""Starting the service: settings from the command line's values, the
token (read, or made for a loopback service and written beside the
queue), and uvicorn."""

from __future__ import annotations

import os
import secrets
import sys
from pathlib import Path

from portal_harness.core.errors import ConfigError
from portal_harness.core.paths import ResultsLayout
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment.limits import Limits
from portal_harness.service.security import TOKEN_ENV, is_loopback, read_token
from portal_harness.service.settings import DEFAULT_MAX_BODY_BYTES, SPOOL_NAME, ServiceSettings

TOKEN_FILE_NAME = "token"


def settings_from(
    results: Path,
    renderer: Path,
    roots: list[Path],
    host: str,
    port: int,
    token_file: Path | None,
    scheduler: str | None = None,
    jobs: int | None = None,
    parallel: int = 1,
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
    figures: bool = True,
    nice: int = 0,
    limits: Limits | None = None,
) -> ServiceSettings:
    """ServiceSettings, checked: the roots exist, the renderer answers, and
    a service off loopback has a token. ConfigError otherwise."""
    for root in roots:
        if not root.is_dir():
            raise ConfigError("--root", str(root), "not a folder")
    if parallel < 1:
        raise ConfigError("--parallel", str(parallel), "expected at least 1")
    renderer_version(str(renderer))  # RendererError if it is missing or broken
    token = read_token(token_file)
    layout = ResultsLayout(results.resolve())
    if token is None:
        if not is_loopback(host):
            raise ConfigError(
                "--host", host, f"off loopback every request needs a token: give --token-file or ${TOKEN_ENV}"
            )
        token = _made_token(layout)
    return ServiceSettings(
        layout=layout,
        renderer=str(renderer.resolve()),
        roots=tuple(r.resolve() for r in roots),
        token=token,
        host=host,
        port=port,
        scheduler=scheduler,
        jobs=jobs,
        parallel=parallel,
        max_body_bytes=max_body_bytes,
        figures=figures,
        nice=nice,
        limits=limits or Limits(),
    )


def _made_token(layout: ResultsLayout) -> str:
    """A random token for a loopback service started without one, written
    (mode 0600) to results/service/token for the local user to read."""
    folder = layout.root / SPOOL_NAME
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / TOKEN_FILE_NAME
    token = secrets.token_urlsafe(24)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(token + "\n")
    print(f"portal-harness serve: no token given: writes need the one in {path}", file=sys.stderr)
    return token


def serve(settings: ServiceSettings) -> int:
    import uvicorn

    from portal_harness.service.app import create_app

    print(
        f"portal-harness serve: http://{settings.host}:{settings.port}/ (API docs at /docs), "
        f"results {settings.layout.root}, roots {', '.join(map(str, settings.roots))}",
        file=sys.stderr,
    )
    uvicorn.run(
        create_app(settings),
        host=settings.host,
        port=settings.port,
        log_level="warning",
        timeout_graceful_shutdown=3,
    )
    return 0
