"""The service's HTTP API and pages (FastAPI): routes only; the queue,
the workers, the views, the checks are the sibling modules'.

Reads are open on a loopback address; writes (submit, cancel, delete)
need `Authorization: Bearer TOKEN`; off loopback every request needs it
(or `?token=` for what a browser loads itself: pages, EventSource).
"""

from __future__ import annotations

import asyncio
import importlib
import json
import os
import shutil
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import anyio
from fastapi import Depends, FastAPI, Request, Response
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles

from portal_harness import __version__
from portal_harness.execution.plan import plan_runs
from portal_harness.execution.renderer import renderer_version
from portal_harness.experiment.loader import load_experiment
from portal_harness.service import events, images, submission
from portal_harness.service import queue as q
from portal_harness.service.dispatcher import Dispatcher
from portal_harness.service.guard import Guard
from portal_harness.service.security import token_matches
from portal_harness.service.settings import ServiceSettings
from portal_harness.service.views import Cached, Views
from portal_harness.service.worker import LOG_NAME, bundle_dir, write_viewer_bundle

STATIC = Path(__file__).resolve().parent / "static"
VIEWER_STATIC = Path(__file__).resolve().parent.parent / "viewer" / "static"
YAML_TYPES = ("application/yaml", "application/x-yaml", "text/yaml", "text/x-yaml")
LOG_TAIL_BYTES = 16384


class ApiError(Exception):
    """An error answered as JSON `{message, ...}` with its HTTP status."""

    def __init__(self, status: int, message: str, **extra: Any) -> None:
        self.status = status
        self.body = {"message": message, **extra}
        super().__init__(message)


def _swagger_assets() -> Path | None:
    try:
        import swagger_ui_bundle  # type: ignore[import-untyped]
    except ImportError:
        return None
    return Path(swagger_ui_bundle.swagger_ui_path)


def create_app(settings: ServiceSettings) -> FastAPI:
    queue = q.Queue(settings.layout.index_path)
    views = Views(settings.layout, queue, ttl_s=settings.poll_s)
    dispatcher = Dispatcher(settings, queue)
    pngs = images.PngCache()
    bundle_lock = threading.Lock()

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        settings.layout.root.mkdir(parents=True, exist_ok=True)
        queue.create()
        dispatcher.start()
        views.start()
        try:
            yield
        finally:
            views.stop()
            dispatcher.stop()

    app = FastAPI(
        title="portal-harness service",
        version=__version__,
        description="Submit experiments (their YAML), follow their sweeps, fetch images, summaries and figures. "
        "See docs/service.md.",
        docs_url=None,
        redoc_url=None,
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.dispatcher = dispatcher

    @app.exception_handler(ApiError)
    async def api_error(_: Request, e: ApiError) -> JSONResponse:
        return JSONResponse(e.body, status_code=e.status)

    @app.exception_handler(submission.SubmissionError)
    async def refused(_: Request, e: submission.SubmissionError) -> JSONResponse:
        return JSONResponse(e.to_json(), status_code=422)

    app.add_middleware(Guard, settings=settings)

    def require_token(request: Request) -> None:
        if not token_matches(settings.token, request.headers.get("authorization")):
            raise ApiError(401, "this request writes: it needs Authorization: Bearer TOKEN")

    def row_of(experiment_id: str) -> dict[str, Any]:
        row = queue.get(experiment_id)
        if row is None:
            raise ApiError(404, f"no experiment {experiment_id!r}")
        return row

    building: dict[str, asyncio.Future[Cached]] = {}

    async def view_of(row: dict[str, Any]) -> Cached:
        """The cache to answer `row` with: at once if one is servable (views.servable), else built in a
        thread, one build per experiment however many reads wait for it (50 clients reading an experiment
        the moment it finishes made 50 threads queue on one lock, and 0.8 s p95 reads)."""
        found = views.servable(row)
        if found is not None:
            return found
        experiment_id = str(row["id"])
        task = building.get(experiment_id)
        if task is None:
            task = asyncio.ensure_future(anyio.to_thread.run_sync(views.current, row))
            building[experiment_id] = task
            task.add_done_callback(lambda _: building.pop(experiment_id, None))
        return await asyncio.shield(task)

    # --- experiments -------------------------------------------------------------------------------------------

    @app.post("/api/experiments", status_code=202, dependencies=[Depends(require_token)], tags=["experiments"])
    async def submit(request: Request) -> JSONResponse:
        """Queues an experiment: the body is its YAML (`Content-Type: application/yaml`), validated as
        `portal-harness sweep` validates a file; its paths name files inside the --root folders.
        422 with `{file, key, line, column, message}` if refused."""
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if kind not in YAML_TYPES:
            raise ApiError(415, f"expected Content-Type: application/yaml, got {kind or 'none'!r}")
        body = bytearray()
        async for chunk in request.stream():
            body += chunk
            if len(body) > settings.max_body_bytes:
                raise ApiError(413, f"request body over the limit of {settings.max_body_bytes} bytes")
        try:
            text = body.decode("utf-8")
        except UnicodeDecodeError as e:
            raise submission.SubmissionError(f"not UTF-8 text: {e.reason} at byte {e.start}") from None
        experiment_id = q.new_id()
        return await anyio.to_thread.run_sync(_queue_submission, experiment_id, text)

    def _queue_submission(experiment_id: str, text: str) -> JSONResponse:
        # Everything is checked (the limits too) before anything is made: no folder, no row if refused.
        experiment, base = submission.validate(text, settings.renderer, settings.roots, settings.limits)
        other = queue.active_with_name(experiment.name)
        if other is not None:
            raise ApiError(409, f"experiment {experiment.name!r} is already queued or running (id {other})", id=other)
        planned = plan_runs(experiment, renderer_version(settings.renderer))
        rows = [
            q.PlannedRunRow(r.key, r.point.id, r.strategy, r.replicate, r.reference, r.spec.spp, r.spec.time_s)
            for r in planned
        ]
        folder = settings.submission_dir(experiment_id)
        folder.mkdir(parents=True, exist_ok=False)
        try:
            (folder / submission.SUBMITTED_NAME).write_text(text)
            queue.add(experiment_id, experiment.name, folder / submission.SUBMITTED_NAME, base, rows)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        dispatcher.wake()
        return JSONResponse(
            {"id": experiment_id, "name": experiment.name, "runs": len(rows)},
            status_code=202,
            headers={"Location": f"/api/experiments/{experiment_id}"},
        )

    @app.get("/api/experiments", tags=["experiments"])
    async def list_experiments() -> Response:
        """Every experiment, newest first: id, name, status, times, progress (0..1), error, run_count (planned
        runs) and renders (its renders by status)."""
        rows = queue.all()  # one query; the rest is cached (views.py): no thread unless a view must be built
        statuses = [views.status(row, await view_of(row)) for row in rows]
        body = json.dumps(statuses, separators=(",", ":"))
        return Response(body, media_type="application/json")

    @app.get("/api/experiments/{experiment_id}", tags=["experiments"])
    async def get_experiment(experiment_id: str, runs: bool = True) -> Response:
        """An experiment with its renders: `runs` lists each run (role `run`) and, once the sweep planned them,
        its references, reference parts, pilots and region maps, each with status, progress, spp, time_s
        and error (with the renderer's stderr tail when it failed). With `?runs=false`, the status only
        (as the list has it): its cost does not grow with the experiment's runs."""
        row = queue.get(experiment_id)  # one query; the rest is cached (views.py)
        if row is None:
            raise ApiError(404, f"no experiment {experiment_id!r}")
        cached = await view_of(row)
        if not runs:
            body = json.dumps(views.status(row, cached), separators=(",", ":")).encode()
        else:
            views.watch(experiment_id)
            body = views.detail_of(row, cached)
        return Response(body, media_type="application/json")

    @app.delete("/api/experiments/{experiment_id}", dependencies=[Depends(require_token)], tags=["experiments"])
    def delete_experiment(experiment_id: str, purge: bool = False) -> JSONResponse:
        """Cancels a queued or running experiment (its renders in progress stop; nothing half-written is
        installed). `?purge=true` also deletes its record and submitted file (not its runs, which other
        experiments may share): only once it is not running."""
        row = row_of(experiment_id)
        status = row["status"]
        if status == q.RUNNING:
            if purge:
                raise ApiError(409, "it is running: cancel it first (DELETE without purge), then purge")
            queue.request_cancel(experiment_id)
            dispatcher.cancel(experiment_id)
            return JSONResponse({"id": experiment_id, "status": "cancelling"}, status_code=202)
        if status == q.QUEUED:
            queue.request_cancel(experiment_id)
            queue.finish(experiment_id, q.CANCELLED, "cancelled before it started", only_if=q.QUEUED)
        if purge:
            queue.delete(experiment_id)
            shutil.rmtree(settings.submission_dir(experiment_id), ignore_errors=True)
            views.get(experiment_id, fresh=True)
            return JSONResponse({"id": experiment_id, "status": "deleted"})
        current = queue.get(experiment_id) or row
        return JSONResponse({"id": experiment_id, "status": current["status"]})

    @app.get("/api/experiments/{experiment_id}/events", tags=["experiments"])
    async def experiment_events(experiment_id: str) -> StreamingResponse:
        """Server-sent events: `status`, `progress` (of the experiment, and of each render from the
        renderer's JSON stream), `end`. See service/events.py."""
        row_of(experiment_id)
        return StreamingResponse(
            events.stream(views, experiment_id, settings.poll_s),
            media_type="text/event-stream",
            headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
        )

    @app.get("/api/experiments/{experiment_id}/log", tags=["experiments"])
    def experiment_log(experiment_id: str) -> Response:
        """The tail of the sweep's log (what `portal-harness sweep` prints)."""
        row_of(experiment_id)
        path = settings.submission_dir(experiment_id) / LOG_NAME
        try:
            with open(path, "rb") as f:
                f.seek(0, os.SEEK_END)
                f.seek(max(0, f.tell() - LOG_TAIL_BYTES))
                data = f.read()
        except OSError:
            data = b""
        return Response(data.decode(errors="replace"), media_type="text/plain; charset=utf-8")

    @app.get("/api/experiments/{experiment_id}/experiment.yaml", tags=["experiments"])
    def experiment_file(experiment_id: str) -> FileResponse:
        """The experiment as submitted."""
        row = row_of(experiment_id)
        return FileResponse(row["file"], media_type="application/yaml")

    @app.get("/api/experiments/{experiment_id}/summary.{fmt}", tags=["results"])
    def experiment_summary(experiment_id: str, fmt: str) -> FileResponse:
        """The tidy summary of the last sweep (`csv` or `json`): one row per point, strategy and region."""
        row = row_of(experiment_id)
        if fmt not in ("csv", "json"):
            raise ApiError(404, "expected summary.csv or summary.json")
        path = settings.layout.summary_csv(row["name"]) if fmt == "csv" else settings.layout.summary_json(row["name"])
        if not path.is_file():
            raise ApiError(404, f"no summary yet (the experiment is {row['status']})")
        return FileResponse(path, media_type="text/csv" if fmt == "csv" else "application/json")

    @app.get("/api/experiments/{experiment_id}/figures", tags=["results"])
    def experiment_figures(experiment_id: str) -> list[str]:
        """The figure files (PNG and PDF) written after the sweep."""
        row = row_of(experiment_id)
        return _figures(str(row["name"]))

    def _figures(name: str) -> list[str]:
        folder = settings.layout.figures_dir
        try:
            names = os.listdir(folder)
        except OSError:
            return []
        return sorted(n for n in names if n.startswith(f"{name}_") and n.endswith((".png", ".pdf")))

    @app.get("/api/experiments/{experiment_id}/figures/{file}", tags=["results"])
    def experiment_figure(experiment_id: str, file: str) -> FileResponse:
        row = row_of(experiment_id)
        if file not in _figures(str(row["name"])):
            raise ApiError(404, f"no figure {file!r} of this experiment")
        return FileResponse(settings.layout.figures_dir / file)

    @app.get("/api/experiments/{experiment_id}/viewer/{path:path}", tags=["results"])
    def experiment_viewer(experiment_id: str, path: str) -> FileResponse:
        """The comparison viewer's bundle of a finished experiment (written once, then cached)."""
        row = row_of(experiment_id)
        if "\x00" in path or len(path) > 1024:
            raise ApiError(404, "no such file in the viewer's bundle")
        try:
            importlib.import_module("portal_harness.viewer.bundle")
        except ImportError:
            raise ApiError(
                503, "the comparison viewer is not installed in this service (no portal_harness.viewer.bundle)"
            ) from None
        if row["status"] != q.DONE:
            raise ApiError(409, f"the viewer needs a finished experiment; this one is {row['status']}")
        folder = bundle_dir(settings.layout, str(row["name"]))
        with bundle_lock:
            if not folder.is_dir():
                experiment = load_experiment(Path(row["file"]), settings.renderer, relative_to=Path(row["base"]))
                write_viewer_bundle(settings.layout, experiment)
        target = (folder / path).resolve()
        top = folder.resolve()
        if os.path.commonpath([str(top), str(target)]) != str(top) or not target.is_file():
            raise ApiError(404, f"no file {path!r} in the viewer's bundle")
        return FileResponse(target)

    # --- images ------------------------------------------------------------------------------------------------

    def run_image(key: str, image: str | None) -> Path:
        """A finished run's final image, or its snapshot named `image`; 404 otherwise."""
        run = images.find_run(settings.layout, key)
        if run is None:
            raise ApiError(404, f"no finished image of run {key!r}")
        path = images.image_of(run, image)
        if path is None:
            raise ApiError(404, f"run {key!r} has no image {image!r}")
        return path

    @app.get("/api/runs/{key}/image.png", tags=["results"])
    def run_png(key: str, image: str | None = None) -> Response:
        """The run's final image (or its snapshot `image`, a file name of the run's folder such as the
        viewer's bundle names), tone-mapped with the exposure of its reference (its own if it has none)."""
        path = run_image(key, image)
        ref_key = queue.reference_of(key)
        ref = images.find_run(settings.layout, ref_key) if ref_key else None
        data = pngs.png(path, ref.final if ref is not None else None)
        return Response(data, media_type="image/png", headers={"Cache-Control": "no-cache"})

    @app.get("/api/runs/{key}/image.exr", tags=["results"])
    def run_exr(key: str, image: str | None = None) -> FileResponse:
        """The run's final EXR (linear radiance and the variance of the mean), or its snapshot `image`."""
        path = run_image(key, image)
        name = f"{key}.exr" if image is None else f"{key}_{image}"
        return FileResponse(path, media_type="image/x-exr", filename=name)

    # --- pages -------------------------------------------------------------------------------------------------

    @app.get("/", include_in_schema=False)
    def page() -> FileResponse:
        return FileResponse(STATIC / "index.html", media_type="text/html")

    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    if VIEWER_STATIC.is_dir():
        app.mount("/viewer", StaticFiles(directory=VIEWER_STATIC), name="viewer")
    assets = _swagger_assets()
    if assets is not None:
        app.mount("/docs-assets", StaticFiles(directory=assets), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        if assets is None:
            raise ApiError(503, "swagger-ui-bundle is not installed: /openapi.json has the API")
        return get_swagger_ui_html(
            openapi_url="/openapi.json",
            title="portal-harness service: API",
            swagger_js_url="/docs-assets/swagger-ui-bundle.js",
            swagger_css_url="/docs-assets/swagger-ui.css",
            swagger_favicon_url="/docs-assets/favicon-32x32.png",
        )

    return app
