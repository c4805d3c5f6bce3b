"""Validation primitives for YAML configs: typed access with file- and
key-qualified errors, and YAML reading with line:column."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from portal_harness.core.cores import available_cores
from portal_harness.core.errors import ConfigError

# Dotted key (as Reader names it: `sweep.params.s_L.1`) -> (line, column), 1-based.
KeyLines = dict[str, tuple[int, int]]


class Reader:
    """Typed access to a YAML mapping with file/key-qualified errors; with
    `lines` (read_yaml_lines), each error also names the key's line."""

    def __init__(self, file: str, lines: KeyLines | None = None) -> None:
        self.file = file
        self.lines: KeyLines = lines or {}

    def fail(self, key: str, message: str) -> ConfigError:
        line = self.line_of(key)
        return ConfigError(self.file, key, message, *(line if line else (None, None)))

    def line_of(self, key: str) -> tuple[int, int] | None:
        """The line of `key`, else of the nearest enclosing key in the file."""
        parts = key.split(".") if key else []
        while parts:
            found = self.lines.get(".".join(parts))
            if found is not None:
                return found
            parts.pop()
        return None

    def mapping(
        self, node: Any, key: str, allowed: set[str], required: frozenset[str] | set[str] = frozenset()
    ) -> dict[str, Any]:
        if not isinstance(node, dict):
            raise self.fail(key, f"expected a mapping, got {kind_of(node)}")
        for k in node:
            if not isinstance(k, str) or k not in allowed:
                raise self.fail(join_key(key, str(k)), f"unknown key (expected one of {', '.join(sorted(allowed))})")
        for k in sorted(required):
            if k not in node:
                raise self.fail(join_key(key, k), "missing required key")
        return node

    def number(self, node: Any, key: str, minimum: float = 0.0, positive: bool = False) -> float:
        if isinstance(node, bool) or not isinstance(node, (int, float)):
            raise self.fail(key, f"expected a number, got {kind_of(node)}")
        if node < minimum or (positive and node <= 0):
            bound = "> 0" if positive else f">= {minimum}"
            raise self.fail(key, f"expected a number {bound}, got {node}")
        return float(node)

    def integer(self, node: Any, key: str, minimum: int = 0) -> int:
        if isinstance(node, bool) or not isinstance(node, int):
            raise self.fail(key, f"expected an integer, got {kind_of(node)}")
        if node < minimum:
            raise self.fail(key, f"expected an integer >= {minimum}, got {node}")
        return int(node)

    def string(self, node: Any, key: str) -> str:
        if not isinstance(node, str) or not node:
            raise self.fail(key, f"expected a non-empty string, got {kind_of(node)}")
        return node

    def choice(self, node: Any, key: str, choices: tuple[str, ...], what: str) -> str:
        s = self.string(node, key)
        if s not in choices:
            raise self.fail(key, f"unknown {what} {s!r} (expected {'|'.join(choices)})")
        return s

    def scalar(self, node: Any, key: str) -> Any:
        if isinstance(node, (dict, list)) or node is None:
            raise self.fail(key, f"expected a scalar (number, string or boolean), got {kind_of(node)}")
        return node

    def sequence(self, node: Any, key: str, non_empty: bool = True) -> list[Any]:
        if not isinstance(node, list):
            raise self.fail(key, f"expected a list, got {kind_of(node)}")
        if non_empty and not node:
            raise self.fail(key, "expected a non-empty list")
        return node


def kind_of(node: Any) -> str:
    if node is None:
        return "nothing"
    if isinstance(node, bool):
        return f"a boolean ({node})"
    if isinstance(node, dict):
        return "a mapping"
    if isinstance(node, list):
        return "a list"
    if isinstance(node, str):
        return f"the string {node!r}"
    return f"{type(node).__name__} {node!r}"


def join_key(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def read_yaml(path: Path, what: str) -> Any:
    """Parses a YAML file; a missing file or a syntax error is a ConfigError with file:line:column."""
    return read_yaml_lines(path, what)[0]


def _key_lines(node: yaml.Node | None, prefix: str, out: KeyLines) -> None:
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            key = join_key(prefix, str(key_node.value))
            out.setdefault(key, (key_node.start_mark.line + 1, key_node.start_mark.column + 1))
            _key_lines(value_node, key, out)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            key = join_key(prefix, str(i))
            out.setdefault(key, (item.start_mark.line + 1, item.start_mark.column + 1))
            _key_lines(item, key, out)


def read_yaml_lines(path: Path, what: str) -> tuple[Any, KeyLines]:
    """read_yaml, and the line and column of every key and sequence item
    (named as Reader names them), for errors that point into the file."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(str(path), "", f"{what} not found") from None
    except OSError as e:
        raise ConfigError(str(path), "", f"cannot read {what}: {e.strerror}") from None
    try:
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        data = yaml.load(text, Loader=loader)
        lines: KeyLines = {}
        _key_lines(yaml.compose(text, Loader=loader), "", lines)
        return data, lines
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark is not None else str(path)
        raise ConfigError(where, "", f"YAML syntax error: {e.problem}") from None
    except yaml.YAMLError as e:
        raise ConfigError(str(path), "", f"YAML error: {e}") from None


def parse_threads(node: Any, reader: Reader, key: str) -> int:
    """A thread count, or `auto`: the cores this process may run on."""
    if node == "auto":
        return available_cores()
    return reader.integer(node, key, minimum=1)
