"""Validation primitives for YAML configs: typed access with file- and
key-qualified errors, and YAML reading with line:column."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import yaml

from portal_harness.core.cores import available_cores
from portal_harness.core.errors import ConfigError

# Dotted key (as Reader names it: `sweep.params.s_L.1`) -> (line, column), 1-based.
KeyLines = dict[str, tuple[int, int]]

# The renderer's own limits (renderer/src/config): threads, samples per pixel, seeds.
THREADS_MAX = 256
SPP_MAX = 2**31 - 1
MAX_STRING = 4096
MAX_NAME = 100
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}", re.ASCII)  # MAX_NAME characters
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")

# The largest integer a config may hold: the index's (SQLite) 64-bit signed integers.
INT_MAX_64 = 2**63 - 1
SEED_MAX = INT_MAX_64  # the renderer's are below 2^64, the index's below 2^63
# A number in exponent form without a dot (`1e12`, `-2E-3`): YAML 1.2 reads it as
# a number, YAML 1.1 (PyYAML) as a string. The harness reads it as the number,
# wherever a number is expected (number(), integer(), swept and fixed values).
_EXPONENT_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d{1,4}$")


def exponent_number(node: Any) -> Any:
    """`node` as a float if it is a string in exponent form (`1e12`), else `node` itself."""
    if isinstance(node, str) and _EXPONENT_NUMBER.match(node.strip()):
        return float(node)
    return node


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

    def number(
        self, node: Any, key: str, minimum: float = 0.0, positive: bool = False, maximum: float = math.inf
    ) -> float:
        node = exponent_number(node)
        if isinstance(node, bool) or not isinstance(node, (int, float)):
            raise self.fail(key, f"expected a number, got {kind_of(node)}")
        if isinstance(node, int) and abs(node) > INT_MAX_64:
            raise self.fail(key, f"expected a number, got an integer of {len(str(abs(node)))} digits")
        if not math.isfinite(node):
            raise self.fail(key, f"expected a finite number, got {node}")
        if node < minimum or (positive and node <= 0):
            bound = "> 0" if positive else f">= {minimum}"
            raise self.fail(key, f"expected a number {bound}, got {node}")
        if node > maximum:
            raise self.fail(key, f"expected a number <= {maximum:g}, got {node:g}")
        return float(node)

    def integer(self, node: Any, key: str, minimum: int = 0, maximum: int = INT_MAX_64) -> int:
        node = exponent_number(node)
        if isinstance(node, float) and math.isfinite(node) and node.is_integer() and not isinstance(node, bool):
            node = int(node)  # `1e3`: an integer written in exponent form
        if isinstance(node, bool) or not isinstance(node, int):
            raise self.fail(key, f"expected an integer, got {kind_of(node)}")
        if node < minimum:
            raise self.fail(key, f"expected an integer >= {minimum}, got {_short(node)}")
        if node > maximum:
            raise self.fail(key, f"expected an integer <= {maximum}, got {_short(node)}")
        return int(node)

    def string(self, node: Any, key: str) -> str:
        if not isinstance(node, str) or not node:
            raise self.fail(key, f"expected a non-empty string, got {kind_of(node)}")
        if len(node) > MAX_STRING:
            raise self.fail(key, f"expected at most {MAX_STRING} characters, got {len(node)}")
        if _CONTROL.search(node):
            raise self.fail(key, "expected text without control characters (NUL, newline, ...)")
        return node

    def name(self, node: Any, key: str) -> str:
        """A name that becomes a file name (an experiment's): ASCII letters,
        digits, `.`, `_`, `-`, not starting with `.` or `-`, at most MAX_NAME."""
        s = self.string(node, key)
        if not NAME.fullmatch(s):
            raise self.fail(
                key,
                f"expected a plain name usable as a file name (ASCII letters, digits, '.', '_', '-', "
                f"starting with a letter or digit, at most {MAX_NAME} characters), got {kind_of(s)}",
            )
        return s

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


def _short(value: int) -> str:
    """An integer as text, its digits counted when it is long."""
    text = str(value)
    return text if len(text) <= 24 else f"an integer of {len(text.lstrip('-'))} digits"


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
        return f"the string {node[:60]!r}" + ("..." if len(node) > 60 else "")
    if isinstance(node, int) and len(str(node)) > 24:
        return _short(node)
    return f"{type(node).__name__} {str(node)[:60]}"


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
    except (ValueError, OverflowError, RecursionError) as e:
        # e.g. an integer of more digits than Python converts, or nesting too deep to read
        raise ConfigError(str(path), "", f"YAML value refused: {str(e)[:200]}") from None


def parse_threads(node: Any, reader: Reader, key: str) -> int:
    """A thread count, or `auto`: the cores this process may run on."""
    if node == "auto":
        return available_cores()
    return reader.integer(node, key, minimum=1, maximum=THREADS_MAX)
