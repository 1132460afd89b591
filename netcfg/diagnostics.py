"""Diagnostics: every problem netcfg reports names a file, a line, a column and what to do."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Literal

Severity = Literal["error", "warning"]


@dataclass(frozen=True)
class Position:
    file: str
    line: int  # 1-based
    column: int  # 1-based


@dataclass(frozen=True)
class Diagnostic:
    code: str
    message: str
    file: str
    line: int
    column: int
    severity: Severity = "error"

    def as_json(self) -> dict[str, object]:
        d = asdict(self)
        del d["severity"]
        return d

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}: {self.severity}: {self.message} [{self.code}]"


class SpecError(Exception):
    """Raised when a spec cannot be loaded or resolved; carries every diagnostic found."""

    def __init__(self, diagnostics: list[Diagnostic]):
        self.diagnostics = diagnostics
        super().__init__("\n".join(str(d) for d in diagnostics))


class Collector:
    """Collects diagnostics so that one run reports every problem, not just the first."""

    def __init__(self) -> None:
        self.items: list[Diagnostic] = []

    def add(self, code: str, message: str, pos: Position, severity: Severity = "error") -> None:
        self.items.append(Diagnostic(code, message, pos.file, pos.line, pos.column, severity))

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity == "error"]

    @property
    def warnings(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity == "warning"]

    def raise_if_errors(self) -> None:
        if self.errors:
            raise SpecError(sorted(self.items, key=_order))


def _order(d: Diagnostic) -> tuple[str, int, int, str]:
    return (d.file, d.line, d.column, d.code)


def sort_diagnostics(items: list[Diagnostic]) -> list[Diagnostic]:
    return sorted(items, key=_order)
