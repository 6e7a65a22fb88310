"""Problems found in a model: errors and warnings with their file, line and column.

The loader and the checker collect every problem of a model in one run into `Diagnostics`;
`ModelErrors` is the exception that carries them when a model cannot be compiled.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple

from umlbot.base.errors import ModelError

Severity = Literal["error", "warning"]


class Location(NamedTuple):
    """A place in a model source file; line and column are 1-based. (A tuple: cheap to make, and
    sorts by file, line, column.)"""

    file: str
    line: int = 1
    column: int = 1


@dataclass(frozen=True)
class Diagnostic:
    """One problem; `str()` gives the `file:line:col: error: message` form."""

    severity: Severity
    message: str
    location: Location

    def __str__(self) -> str:
        loc = self.location
        return f"{loc.file}:{loc.line}:{loc.column}: {self.severity}: {self.message}"


@dataclass
class Diagnostics:
    """The problems of one model, in the order found; `sorted()` gives the reporting order."""

    items: list[Diagnostic] = field(default_factory=list)

    def error(self, message: str, location: Location) -> None:
        self.items.append(Diagnostic("error", message, location))

    def warning(self, message: str, location: Location) -> None:
        self.items.append(Diagnostic("warning", message, location))

    def add_model_error(self, exc: ModelError) -> Diagnostic:
        """Report `exc` as an error; the `Diagnostic` made of it."""
        self.error(exc.message, Location(exc.file, exc.line, exc.column))
        return self.items[-1]

    def add_note(self, diagnostic: Diagnostic, note: str) -> None:
        """Say `note` in parentheses after the message of a problem reported before."""
        index = self.items.index(diagnostic)
        self.items[index] = replace(diagnostic, message=f"{diagnostic.message} ({note})")

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity == "error"]

    @property
    def warnings(self) -> list[Diagnostic]:
        return [d for d in self.items if d.severity == "warning"]

    @property
    def has_errors(self) -> bool:
        return any(d.severity == "error" for d in self.items)

    def sorted(self) -> list[Diagnostic]:
        """Every problem once, by file, line and column."""
        unique = {(d.location, d.severity, d.message): d for d in self.items}
        return [unique[key] for key in sorted(unique)]


class ModelErrors(ModelError):
    """A model has errors; `diagnostics` holds all of them (and the warnings).

    The exception's own file/line/column/message are those of the first error.
    """

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        errors = [d for d in diagnostics if d.severity == "error"]
        first = errors[0] if errors else Diagnostic("error", "model has errors", Location("<model>"))
        more = f" (and {len(errors) - 1} more error(s))" if len(errors) > 1 else ""
        loc = first.location
        super().__init__(first.message + more, loc.file, loc.line, loc.column)
        self.diagnostics = diagnostics
