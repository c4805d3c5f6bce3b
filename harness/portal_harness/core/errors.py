"""Exceptions of the harness: each carries a message meant for the user."""

from __future__ import annotations


class HarnessError(Exception):
    """An error the command line reports as one line and turns into an exit status."""

    exit_status = 1


class ConfigError(HarnessError):
    """A bad experiment or command-line configuration, found before any render."""

    exit_status = 2

    def __init__(self, file: str, key: str, message: str, line: int | None = None, column: int | None = None) -> None:
        self.file = file
        self.key = key
        self.message = message
        self.line = line  # 1-based, of the key in the file where known (schema.Reader)
        self.column = column
        at = f"{file}:{line}:{column or 1}" if line is not None else file
        where = f"{at}: {key}" if key else at
        super().__init__(f"{where}: {message}")


class RendererError(HarnessError):
    """The renderer binary is missing or does not answer --version."""

    exit_status = 2


class CorruptExrError(HarnessError):
    """An EXR file that cannot be read completely or lacks what the contract promises."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: corrupt or truncated EXR: {reason}")
