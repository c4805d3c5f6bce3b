"""The manifest's git record: a sweep's own outputs under results/ do not
make the checkout dirty; a change to the code does."""

from __future__ import annotations

import subprocess
from pathlib import Path

from portal_harness.analysis.manifest import git_commit


def _git(root: Path, *args: str) -> None:
    subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True)


def _checkout(tmp_path: Path) -> Path:
    root = tmp_path / "repo"
    for name in ("configs/a.yaml", "renderer/src/a.c", "results/experiments/x_full/summary.csv"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text("v1\n")
    _git(root, "init", "-q")
    _git(root, "add", ".")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--no-verify", "-m", "first")
    return root


def test_rewritten_or_moved_results_are_not_dirty(tmp_path: Path) -> None:
    root = _checkout(tmp_path)
    record = git_commit(root)
    assert record is not None and record["dirty"] is False and len(record["commit"]) == 40
    (root / "results/experiments/x_full/summary.csv").write_text("v2\n")
    assert git_commit(root) == {**record, "dirty": False}
    (root / "results/experiments/x_full/summary.csv").unlink()
    assert git_commit(root) == {**record, "dirty": False}


def test_changed_code_is_dirty(tmp_path: Path) -> None:
    root = _checkout(tmp_path)
    (root / "renderer/src/a.c").write_text("v2\n")
    record = git_commit(root)
    assert record is not None and record["dirty"] is True


def test_outside_git_is_none(tmp_path: Path) -> None:
    assert git_commit(tmp_path) is None
