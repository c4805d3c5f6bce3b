"""The docs name only what exists.

Every repository path, `make` target and `portal-harness` subcommand that the
README, CONTRIBUTING.md, CHANGELOG.md and docs/*.md name must exist: a path in
the tree, a target of the Makefile, a subcommand of the harness's parser. Paths
are read from code spans, fenced code blocks and Markdown links; targets and
subcommands from code only. The README stays the front door: at most 150 lines.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
README_MAX_LINES = 150

# A code token is taken for a repository path when it starts with one of these.
ROOT_DIRS = ("renderer", "harness", "configs", "results", "tests", "tools", "docs", ".ci", ".githooks")
ROOT_FILES = ("README.md", "CONTRIBUTING.md", "CHANGELOG.md", "Makefile")

# What the build or a run writes: named by the docs, absent from a fresh clone.
GENERATED = (
    ".venv/",
    ".venv-xcheck/",
    "renderer/build",
    "results/runs/",
    "results/references/",
    "results/renders/",
    "results/tmp/",
    "results/service/",
    "results/index.sqlite",
    "results/bench/tmp/",
)
# results/experiments and results/figures keep only the paper-quality (_full) files in git.
GENERATED_UNLESS_FULL = ("results/experiments/", "results/figures/")

# Named before they land: paths another change is about to add (none now).
PENDING: frozenset[str] = frozenset()

# Placeholders (NAME.yaml, DIR/viewer.html, runs/<key>/) and globs name no one file.
PLACEHOLDER = re.compile(r"NAME|DIR\b|KEY\b|FILE\b|PATH\b|HEX|<|>|\*|\.\.\.|…")
CODE_SPAN = re.compile(r"`([^`]+)`")
LINK = re.compile(r"\]\(([^)\s]+)\)")
HTML_COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
MAKE_CALL = re.compile(r"(?<![\w/.-])make((?:\s+[A-Z_]+=\S*)*)\s+([a-z][\w.-]*)")
HARNESS_CALL = re.compile(r"(?<![\w.-])portal-harness\s+([a-z][\w-]*)")
TARGET_LINE = re.compile(r"^([A-Za-z0-9_.][A-Za-z0-9_. -]*?)\s*:(?![=:])", re.MULTILINE)
PHONY_LINE = re.compile(r"^\.PHONY:(.*)$", re.MULTILINE)
ADD_PARSER = re.compile(r"add_parser\(\s*\"([\w-]+)\"")


@dataclass(frozen=True)
class Code:
    """A piece of code in a doc: its text and the line it starts on."""

    text: str
    line: int


def doc_files(root: Path) -> list[Path]:
    """The docs this test checks: the README, CONTRIBUTING, the changelog and docs/*.md."""
    names = [root / "README.md", root / "CONTRIBUTING.md", root / "CHANGELOG.md"]
    return [p for p in names if p.is_file()] + sorted((root / "docs").glob("*.md"))


def makefile_targets(makefile: Path) -> set[str]:
    """Every target the Makefile defines (rule heads and .PHONY names)."""
    text = makefile.read_text(encoding="utf-8")
    targets: set[str] = set()
    for m in TARGET_LINE.finditer(text):
        targets.update(t for t in m.group(1).split() if "$" not in t)
    for m in PHONY_LINE.finditer(text):
        targets.update(m.group(1).split())
    return targets


def harness_subcommands(cli: Path) -> set[str]:
    """The subcommands of `portal-harness`, as its argument parser declares them."""
    return set(ADD_PARSER.findall(cli.read_text(encoding="utf-8")))


def _line_of(text: str, offset: int) -> int:
    return text.count("\n", 0, offset) + 1


def code_pieces(text: str) -> list[Code]:
    """The fenced blocks (line by line) and the inline code spans of a Markdown text."""
    text = HTML_COMMENT.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    pieces: list[Code] = []
    prose: list[str] = []
    fenced = False
    for number, line in enumerate(text.split("\n"), start=1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            prose.append("")
        elif fenced:
            pieces.append(Code(line, number))
            prose.append("")
        else:
            prose.append(line)
    rest = "\n".join(prose)
    pieces += [Code(m.group(1), _line_of(rest, m.start())) for m in CODE_SPAN.finditer(rest)]
    return pieces


def links(text: str) -> list[Code]:
    """Markdown link targets outside code, with their lines."""
    text = HTML_COMMENT.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    return [Code(m.group(1), _line_of(text, m.start())) for m in LINK.finditer(text)]


def expand_braces(token: str) -> list[str]:
    """`film.{h,c}` -> [`film.h`, `film.c`]; every brace group expands."""
    parts = re.split(r"\{([^{}]*,[^{}]*)\}", token)
    fixed, choices = parts[0::2], [p.split(",") for p in parts[1::2]]
    out = []
    for combo in itertools.product(*choices):
        out.append("".join(f + c for f, c in zip(fixed, [*combo, ""], strict=True)))
    return out


def repo_path_tokens(code: str) -> list[str]:
    """The tokens of a piece of code that name a file or folder of the repository."""
    paths = []
    for raw in re.split(r"[\s=\[\]();|'\"]+", code):
        token = re.sub(r"(:\d+)+$", "", raw.strip(".,:`"))
        if not token or PLACEHOLDER.search(token):
            continue
        first = token.split("/", 1)[0]
        if (first in ROOT_DIRS and "/" in token) or token in ROOT_FILES:
            paths.extend(expand_braces(token))
    return paths


def is_generated(path: str) -> bool:
    """A path the build or a run writes, which a fresh clone does not have."""
    if path.startswith(GENERATED):
        return True
    return path.startswith(GENERATED_UNLESS_FULL) and "_full" not in path


def check_doc(doc: Path, root: Path, targets: set[str], subcommands: set[str]) -> list[str]:
    """What `doc` names that does not exist, one `doc:line: message` each."""
    text = doc.read_text(encoding="utf-8")
    name = doc.relative_to(root).as_posix()
    problems: list[str] = []

    def need(path: str, where: Path, line: int, shown: str) -> None:
        resolved = (where / path).resolve()
        try:
            rel = resolved.relative_to(root.resolve()).as_posix()
        except ValueError:
            rel = path
        if rel in PENDING or is_generated(rel) or resolved.exists():
            return
        problems.append(f"{name}:{line}: no such file or folder: {shown}")

    for piece in code_pieces(text):
        for path in repo_path_tokens(piece.text):
            need(path, root, piece.line, path)
        for m in MAKE_CALL.finditer(piece.text):
            if m.group(2) not in targets:
                problems.append(f"{name}:{piece.line}: no make target: make {m.group(2)}")
        for m in HARNESS_CALL.finditer(piece.text):
            if m.group(1) not in subcommands:
                problems.append(f"{name}:{piece.line}: no portal-harness subcommand: {m.group(1)}")
    for link in links(text):
        target = link.text.split("#", 1)[0]
        if not target or re.match(r"[a-z]+:", target):
            continue
        need(target, doc.parent, link.line, link.text)
    return sorted(problems, key=lambda p: int(p.split(":", 2)[1]))


def check_docs(root: Path) -> list[str]:
    """Every problem of every doc of the repository at `root`."""
    targets = makefile_targets(root / "Makefile")
    cli = root / "harness" / "portal_harness" / "cli.py"
    subcommands = harness_subcommands(cli) if cli.is_file() else set()
    return [p for doc in doc_files(root) for p in check_doc(doc, root, targets, subcommands)]


def test_01_every_named_path_target_and_subcommand_exists() -> None:
    problems = check_docs(REPO)
    assert not problems, "\n".join(problems)


def test_02_the_readme_is_the_front_door() -> None:
    lines = (REPO / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, f"README.md has {lines} lines; at most {README_MAX_LINES}"


def test_03_the_checks_find_something_to_check() -> None:
    assert {"figures", "test", "same-images", "bench-ab"} <= makefile_targets(REPO / "Makefile")
    assert {"sweep", "figures", "serve"} <= harness_subcommands(REPO / "harness" / "portal_harness" / "cli.py")
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    named = {p for piece in code_pieces(readme) for p in repo_path_tokens(piece.text)}
    assert "configs/scenes/first_scene.yaml" in named


def test_04_a_fake_doc_with_a_missing_file_and_target_fails(tmp_path: Path) -> None:
    (tmp_path / "Makefile").write_text("all: build\n\ttrue\n.PHONY: test\ntest:\n\ttrue\n", encoding="utf-8")
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "real.yaml").write_text("{}\n", encoding="utf-8")
    (tmp_path / "README.md").write_text(
        "# Fake\n\nRender `configs/real.yaml`, then `configs/missing.yaml`.\n\n"
        "```sh\nmake test\nFULL=1 make nosuchtarget\n```\n\nSee [the guide](docs/gone.md).\n",
        encoding="utf-8",
    )
    problems = check_docs(tmp_path)
    assert problems == [
        "README.md:3: no such file or folder: configs/missing.yaml",
        "README.md:7: no make target: make nosuchtarget",
        "README.md:10: no such file or folder: docs/gone.md",
    ]


def test_05_placeholders_generated_files_and_braces() -> None:
    assert repo_path_tokens("results/experiments/NAME/summary.csv runs/<key>/") == []
    assert repo_path_tokens("renderer/src/base/transform.{h,c}:12") == [
        "renderer/src/base/transform.h",
        "renderer/src/base/transform.c",
    ]
    assert is_generated("results/figures/lampshade_ratio_insets.png")
    assert not is_generated("results/figures/little_lamp_full_insets.png")
