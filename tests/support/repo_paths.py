"""The repository and the real renderer, for the tests outside tests/harness
(tests/bench, tests/tools), which its conftest.py does not reach: each puts
this folder on sys.path and imports what it needs from here."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# The real renderer: $PORTAL_RENDERER if set (as for the harness), else the build's.
REAL_RENDERER = Path(os.environ.get("PORTAL_RENDERER") or REPO / "renderer" / "build" / "render")


@pytest.fixture(name="real_renderer", scope="session")
def real_renderer_fixture() -> Path:
    """The real renderer; the test is skipped until it is built."""
    if not (REAL_RENDERER.is_file() and os.access(REAL_RENDERER, os.X_OK)):
        pytest.skip("renderer/build/render not built yet")
    return REAL_RENDERER
