"""What the service lets in: the bearer token, the addresses that need it
for every request, and the --root folders every path of a submitted
experiment must stay inside."""

from __future__ import annotations

import hmac
import ipaddress
import os
from collections.abc import Sequence
from pathlib import Path

from portal_harness.core.errors import ConfigError

TOKEN_ENV = "PORTAL_HARNESS_TOKEN"


def read_token(token_file: Path | None) -> str | None:
    """The token of --token-file (its first line), else $PORTAL_HARNESS_TOKEN, else None.
    ConfigError if the file cannot be read or is empty."""
    if token_file is not None:
        try:
            lines = token_file.read_text().splitlines()
        except OSError as e:
            raise ConfigError(str(token_file), "", f"cannot read the token file: {e.strerror}") from None
        token = lines[0].strip() if lines else ""
        if not token:
            raise ConfigError(str(token_file), "", "the token file is empty")
        return token
    token = os.environ.get(TOKEN_ENV, "").strip()
    return token or None


def token_matches(expected: str | None, authorization: str | None, query_token: str | None = None) -> bool:
    """True if `Authorization: Bearer T` (or the ?token= of a browser's
    EventSource, which cannot set headers) carries the expected token.
    Compared in constant time, so the answer's timing says nothing of how
    much of a guess was right."""
    if not expected:
        return False
    given = ""
    if authorization:
        scheme, _, value = authorization.partition(" ")
        if scheme.lower() == "bearer":
            given = value.strip()
    if not given and query_token:
        given = query_token
    return hmac.compare_digest(given.encode(), expected.encode())


def is_loopback(host: str) -> bool:
    """True for an address that only this machine can reach (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class PathEscape(ValueError):
    """A path of a submitted experiment that leaves the --root folders."""


def inside(path: Path, roots: Sequence[Path]) -> bool:
    """True if `path`, every symbolic link resolved, lies in one of the (resolved) roots."""
    real = os.path.realpath(path)
    for root in roots:
        top = os.path.realpath(root)
        if os.path.commonpath([top, real]) == top:
            return True
    return False


def resolve_in_roots(text: str, roots: Sequence[Path]) -> tuple[Path, Path]:
    """(root, path) of a path named in a submitted experiment: relative to
    the first root that holds it, or absolute inside a root. PathEscape for
    `..`, for an absolute path elsewhere, and for a symbolic link that leads
    out of its root; FileNotFoundError if no root holds it."""
    candidate = Path(text)
    if ".." in candidate.parts:
        raise PathEscape(f"{text!r}: '..' is not allowed (name files relative to a --root folder)")
    if candidate.is_absolute():
        named = os.path.abspath(candidate)
        for root in roots:
            tops = {os.path.abspath(root), os.path.realpath(root)}
            if any(os.path.commonpath([top, named]) == top for top in tops):
                if not inside(candidate, [root]):
                    raise PathEscape(f"{text!r}: a symbolic link leads outside the --root folders")
                return root, candidate
        raise PathEscape(f"{text!r}: an absolute path outside the --root folders")
    for root in roots:
        path = root / candidate
        if path.exists() or path.is_symlink():
            if not inside(path, [root]):
                raise PathEscape(f"{text!r}: a symbolic link leads outside its --root folder")
            return root, path
    raise FileNotFoundError(f"{text!r}: no such file in the --root folders")
