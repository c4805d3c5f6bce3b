"""Issue 42, item 7: colour-science's warning that its SciPy features are
missing is silenced where colour is imported (core/display.py), and only
that warning: others still show."""

from __future__ import annotations

import subprocess
import sys


def test_01_the_scipy_warning_of_colour_is_silenced_and_no_other() -> None:
    code = "import warnings, portal_harness.core.display; warnings.warn('another warning')"
    done = subprocess.run([sys.executable, "-W", "always", "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "SciPy" not in done.stderr and "another warning" in done.stderr, done.stderr
