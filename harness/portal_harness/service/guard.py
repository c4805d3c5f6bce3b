"""The checks every request passes before any route: the body-size limit
(by Content-Length; a body sent in chunks is counted where it is read) and,
off loopback, the token. A plain ASGI middleware, so that event streams
pass through it untouched."""

from __future__ import annotations

from starlette.datastructures import Headers, QueryParams
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Receive, Scope, Send

from portal_harness.service.security import token_matches
from portal_harness.service.settings import ServiceSettings


class Guard:
    def __init__(self, app: ASGIApp, settings: ServiceSettings) -> None:
        self.app = app
        self.settings = settings

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        length = headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > self.settings.max_body_bytes):
            refused = JSONResponse(
                {"message": f"request body over the limit of {self.settings.max_body_bytes} bytes"}, status_code=413
            )
            await refused(scope, receive, send)
            return
        if self.settings.every_request_needs_token:
            query = QueryParams(scope.get("query_string", b"").decode("latin-1"))
            if not token_matches(self.settings.token, headers.get("authorization"), query.get("token")):
                await unauthorized()(scope, receive, send)
                return
        await self.app(scope, receive, send)


def unauthorized() -> JSONResponse:
    return JSONResponse(
        {"message": "this service needs Authorization: Bearer TOKEN for every request"},
        status_code=401,
        headers={"WWW-Authenticate": "Bearer"},
    )
