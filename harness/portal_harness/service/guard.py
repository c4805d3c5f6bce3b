"""The checks every request passes before any route: the body-size limit
(by Content-Length; a body sent in chunks is counted where it is read) and,
off loopback, the token. A plain ASGI middleware, so that event streams
pass through it untouched.

Off loopback a browser cannot put the token in a header of what it loads
itself (pages, scripts, images, event streams, the viewer's files): a page
opened with `?token=T` gets it back as a cookie (HttpOnly, SameSite=Strict),
which then authorises reads (GET, HEAD) of the same origin. Writes always
need the Authorization header, so a cookie alone can never write (no
cross-site request forgery)."""

from __future__ import annotations

from http.cookies import SimpleCookie

from starlette.datastructures import Headers, MutableHeaders, QueryParams
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from portal_harness.service.security import token_matches
from portal_harness.service.settings import ServiceSettings

COOKIE = "portal_harness_token"
READS = frozenset({"GET", "HEAD"})


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
        if not self.settings.every_request_needs_token:
            await self.app(scope, receive, send)
            return
        query = QueryParams(scope.get("query_string", b"").decode("latin-1"))
        by_query = token_matches(self.settings.token, None, query.get("token"))
        cookie = SimpleCookie(headers.get("cookie", "")).get(COOKIE)
        by_cookie = (
            cookie is not None and scope["method"] in READS and token_matches(self.settings.token, None, cookie.value)
        )
        if not (by_query or by_cookie or token_matches(self.settings.token, headers.get("authorization"))):
            await unauthorized()(scope, receive, send)
            return
        if not by_query:
            await self.app(scope, receive, send)
            return
        token = str(self.settings.token)

        async def send_with_cookie(message: Message) -> None:
            if message["type"] == "http.response.start":
                MutableHeaders(scope=message).append(
                    "set-cookie", f"{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"
                )
            await send(message)

        await self.app(scope, receive, send_with_cookie)


def unauthorized() -> JSONResponse:
    return JSONResponse(
        {"message": "this service needs Authorization: Bearer TOKEN for every request"},
        status_code=401,
        headers={"WWW-Authenticate": "Bearer"},
    )
