"""A submitted experiment (YAML text) made into a validated Experiment,
exactly as `portal-harness sweep` validates a file (config.load_experiment,
which asks the renderer about the scene at every point), after the checks a
service adds: the YAML is safe to load (no alias bombs) and every file the
experiment and its scene read lies inside the --root folders.

Relative paths name files relative to a root folder: the first that holds
the scene is the folder against which the experiment's paths resolve.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from portal_harness.core.errors import ConfigError, HarnessError
from portal_harness.experiment import contract
from portal_harness.experiment.facets import SWEEPABLE_HARNESS_KEYS
from portal_harness.experiment.limits import LimitError, Limits
from portal_harness.experiment.loader import load_experiment
from portal_harness.experiment.model import Experiment, point_overrides
from portal_harness.service.security import PathEscape, inside, resolve_in_roots

SUBMITTED_NAME = "experiment.yaml"
# A YAML document whose aliases expand to more nodes than this is refused
# (an experiment has tens of nodes; a "billion laughs" has 10^9).
MAX_EXPANDED_NODES = 20000
MAX_PATH = 1024  # characters of a path an experiment names
_WHERE = re.compile(r"^(?P<file>.*?):(?P<line>\d+):(?P<column>\d+)$")


@dataclass
class SubmissionError(Exception):
    """A refused submission, as the API's 422 body: file, key, line, column, message."""

    message: str
    file: str = SUBMITTED_NAME
    key: str = ""
    line: int | None = None
    column: int | None = None
    limit: tuple[str, float, float] | None = None  # (name, value, maximum) of a limit broken

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "file": self.file,
            "key": self.key,
            "line": self.line,
            "column": self.column,
            "message": self.message,
        }
        if self.limit is not None:
            name, value, maximum = self.limit
            # JSON has no infinity: a count past any bound (a period of 5e-324) is said as text.
            out["limit"] = {"name": name, "value": value if math.isfinite(value) else str(value), "maximum": maximum}
        return out


def _expanded_size(root: yaml.Node) -> int:
    """Nodes of the document with every alias expanded, counted without
    expanding them (a node's size is memoised); a cycle counts as too many."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        nid = id(node)
        if children_done:
            on_path.discard(nid)
            kids = _children(node)
            sizes[nid] = min(MAX_EXPANDED_NODES + 1, 1 + sum(sizes[id(k)] for k in kids))
            continue
        if nid in sizes:
            continue
        if nid in on_path:
            return MAX_EXPANDED_NODES + 1  # an alias of its own ancestor
        on_path.add(nid)
        stack.append((node, True))
        stack.extend((k, False) for k in _children(node) if id(k) not in sizes)
    return sizes[id(root)]


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


# The tags a plain YAML document resolves to; any other (e.g. !!python/object/apply) is refused.
_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool", "null", "map", "seq", "timestamp"))
# Longer integers than any experiment needs (64 bits have 20 digits), refused before they are converted.
MAX_INTEGER_DIGITS = 40


def _check_nodes(root: yaml.Node) -> None:
    """Refuses, at its key and line, a node of an unknown tag or an integer
    too long to mean anything (Python refuses to convert the longest)."""
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    seen: set[int] = set()
    while stack:
        node, key = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        line, column = node.start_mark.line + 1, node.start_mark.column + 1
        if node.tag not in _TAGS:
            raise SubmissionError(
                f"YAML tag {node.tag[:60]!r} refused (plain YAML values only)", key=key, line=line, column=column
            )
        if node.tag.endswith(":int") and len(str(node.value)) > MAX_INTEGER_DIGITS:
            raise SubmissionError(
                f"an integer of {len(str(node.value))} characters (at most {MAX_INTEGER_DIGITS})",
                key=key,
                line=line,
                column=column,
            )
        if isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                name = str(k.value)[:60] if isinstance(k, yaml.ScalarNode) else "?"
                stack += [(k, key), (v, f"{key}.{name}" if key else name)]
        elif isinstance(node, yaml.SequenceNode):
            stack += [(v, f"{key}.{i}" if key else str(i)) for i, v in enumerate(node.value)]


def check_yaml(text: str) -> dict[str, Any]:
    """The document as data, after refusing syntax errors (with their line),
    several documents, alias bombs and anything but a mapping."""
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        nodes = list(yaml.compose_all(text, Loader=loader))
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark
        raise SubmissionError(
            f"YAML syntax error: {e.problem}",
            line=None if mark is None else mark.line + 1,
            column=None if mark is None else mark.column + 1,
        ) from None
    except yaml.YAMLError as e:
        raise SubmissionError(f"YAML error: {e}") from None
    if len(nodes) != 1:
        raise SubmissionError(f"expected one YAML document, got {len(nodes)}")
    if _expanded_size(nodes[0]) > MAX_EXPANDED_NODES:
        raise SubmissionError(
            f"refused: its aliases expand to more than {MAX_EXPANDED_NODES} nodes (or refer to themselves)"
        )
    _check_nodes(nodes[0])
    try:
        data = yaml.load(text, Loader=loader)
    except yaml.MarkedYAMLError as e:  # e.g. a tag of Python objects, which the safe loader does not build
        mark = e.problem_mark
        raise SubmissionError(
            f"YAML value refused: {e.problem}",
            line=None if mark is None else mark.line + 1,
            column=None if mark is None else mark.column + 1,
        ) from None
    except (yaml.YAMLError, ValueError, OverflowError, RecursionError) as e:
        # e.g. an integer of more digits than Python converts
        raise SubmissionError(f"YAML value refused: {str(e)[:200]}") from None
    if not isinstance(data, dict):
        raise SubmissionError("expected a mapping (an experiment file) at the top level", line=1, column=1)
    return data


def _line_of(text: str, key: str) -> tuple[int, int] | None:
    node = yaml.compose(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    parts = key.split(".")
    for i, part in enumerate(parts):
        if not isinstance(node, yaml.MappingNode):
            return None
        for k, v in node.value:
            if str(k.value) == part:
                if i == len(parts) - 1:
                    return v.start_mark.line + 1, v.start_mark.column + 1
                node = v
                break
        else:
            return None
    return None


def _path_error(text: str, key: str, message: str) -> SubmissionError:
    where = _line_of(text, key)
    return SubmissionError(message, key=key, line=where[0] if where else None, column=where[1] if where else None)


def _resolve(text: str, data: dict[str, Any], key: str, value: Any, roots: tuple[Path, ...]) -> Path:
    if not isinstance(value, str) or not value:
        raise _path_error(text, key, "expected a path (a non-empty string)")
    if len(value) > MAX_PATH or "\x00" in value:
        raise _path_error(text, key, f"expected a path of at most {MAX_PATH} characters, without NUL")
    try:
        root, path = resolve_in_roots(value, roots)
        if not path.is_file():  # a folder: named relative to its root, never by the root's own path
            raise _path_error(text, key, f"{value[:60]!r}: not a file (a folder) in the --root folders")
        return root
    except PathEscape as e:
        raise _path_error(text, key, f"path outside the --root folders: {e}") from None
    except FileNotFoundError as e:
        raise _path_error(text, key, str(e)) from None
    except (OSError, ValueError):  # a name too long for the file system: as good as missing
        raise _path_error(text, key, f"{value[:60]!r}...: no such file in the --root folders") from None


def _paths(data: dict[str, Any]) -> list[tuple[str, Any]]:
    """The paths an experiment names itself (its scene's own files are the renderer's to list)."""
    out: list[tuple[str, Any]] = [("scene", data.get("scene"))]
    figures = data.get("figures")
    if isinstance(figures, dict) and isinstance(figures.get("region_sections"), dict):
        out.append(("figures.region_sections.scene", figures["region_sections"].get("scene")))
    regress = data.get("regress")
    if isinstance(regress, dict) and "baseline" in regress:
        out.append(("regress.baseline", regress["baseline"]))
    return out


def _from_config_error(
    e: ConfigError, stored: Path, roots: tuple[Path, ...], limit: tuple[str, float, float] | None = None
) -> SubmissionError:
    """A ConfigError of the harness or the renderer, with the stored file's
    name replaced by the submission's, and a root's files named relative
    to it. A file outside the roots is not named, nor quoted."""
    file, line, column = e.file, e.line, e.column
    found = _WHERE.match(file)
    if found:
        file, line, column = found["file"], int(found["line"]), int(found["column"])
    if file == str(stored):
        file = SUBMITTED_NAME
    elif os.path.isabs(file):
        if not inside(Path(file), roots):
            return SubmissionError(
                "the scene reads a file outside the --root folders", key=e.key or "scene", line=None, column=None
            )
        for root in roots:
            top = os.path.realpath(root)
            real = os.path.realpath(file)
            if os.path.commonpath([top, real]) == top:
                file = os.path.relpath(real, top)
                break
    return SubmissionError(e.message, file=file, key=e.key, line=line, column=column, limit=limit)


def check_files(experiment: Experiment, renderer: str, roots: tuple[Path, ...]) -> None:
    """Every file the renderer reads for any point of the experiment (the
    scene, its includes, its meshes: an override may name another mesh)
    lies inside the roots."""
    scenes = [experiment.scene]
    if experiment.region_sections is not None:
        scenes.append(experiment.region_sections.scene)
    for scene in scenes:
        for point in experiment.points():
            values = tuple((k, v) for k, v in point.values if k not in SWEEPABLE_HARNESS_KEYS)
            effective = contract.print_config(renderer, scene, point_overrides(experiment.fixed, values))
            for f in effective.files:
                if not inside(f, roots):
                    raise SubmissionError(
                        "the scene reads a file outside the --root folders (an include or a mesh; "
                        "symbolic links are followed)",
                        key="scene",
                    )


def validate(
    text: str, renderer: str, roots: tuple[Path, ...], limits: Limits | None = None
) -> tuple[Experiment, Path]:
    """Validates the submitted text; returns the experiment and the root its
    paths resolve against. SubmissionError if refused. Nothing is left
    behind either way: the text is read from a private temporary folder
    (the caller stores it once everything else has passed)."""
    data = check_yaml(text)
    base: Path | None = None
    for key, value in _paths(data):
        if value is None and key == "scene":
            break  # load_experiment names the missing key, with its line
        root = _resolve(text, data, key, value, roots)
        base = base or root
    with tempfile.TemporaryDirectory(prefix="portal-submission-") as scratch:
        stored = Path(scratch) / SUBMITTED_NAME
        stored.write_text(text)
        try:
            experiment = load_experiment(stored, renderer, relative_to=base or roots[0], limits=limits)
        except LimitError as e:
            raise _from_config_error(e, stored, roots, limit=(e.limit, e.value, e.maximum)) from None
        except ConfigError as e:
            raise _from_config_error(e, stored, roots) from None
        except HarnessError as e:
            raise SubmissionError(str(e).replace(str(stored), SUBMITTED_NAME)) from None
    if experiment.budget is None:
        raise _path_error(text, "budget", "missing (a sweep needs time_s or spp)")
    check_files(experiment, renderer, roots)
    return experiment, base or roots[0]
