"""Errors and warnings of the Mitsuba importer, each naming the XML line."""

from __future__ import annotations

from dataclasses import dataclass, field

from portal_harness.core.errors import HarnessError


class MitsubaImportError(HarnessError):
    """A scene that cannot be imported: `file:line: message`, exit status 2."""

    exit_status = 2

    def __init__(self, file: str, line: int, message: str) -> None:
        self.file = file
        self.line = line
        self.message = message
        super().__init__(f"{file}:{line}: {message}" if line else f"{file}: {message}")


@dataclass
class Report:
    """The warnings of one import, in document order. Each element that is
    not imported as it is gets one warning; identical messages (the same
    ignored parameter on forty shapes) are printed once with every line."""

    file: str
    warnings: list[tuple[int, str]] = field(default_factory=list)

    def warn(self, line: int, message: str) -> None:
        self.warnings.append((line, message))

    def error(self, line: int, message: str) -> MitsubaImportError:
        return MitsubaImportError(self.file, line, message)

    def lines(self) -> list[str]:
        """One `file:line: warning: message` per distinct message, in order of first occurrence."""
        grouped: dict[str, list[int]] = {}
        for line, message in self.warnings:
            grouped.setdefault(message, []).append(line)
        out = []
        for message, where in grouped.items():
            also = f" (also at lines {', '.join(str(n) for n in where[1:])})" if len(where) > 1 else ""
            out.append(f"{self.file}:{where[0]}: warning: {message}{also}")
        return out
