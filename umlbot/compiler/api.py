"""The compiler's front door: check a model folder or file, compile it.

`check_model` returns every problem (errors and warnings) and, when there is no error, the
compiled model; `compile_model` returns the compiled model or raises `ModelErrors` carrying all
problems. Both never raise anything but `ModelError` for a bad model.
"""

from __future__ import annotations

import gc
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from umlbot.base.diagnostics import Diagnostic, Diagnostics, ModelErrors
from umlbot.base.errors import ModelError
from umlbot.compiler.checker import CheckMemo, check_source
from umlbot.compiler.compiled import CompiledModel
from umlbot.compiler.source import LaneCache, SourceModel, Unreadable, load_source


@dataclass(frozen=True)
class CheckResult:
    """The outcome of checking a model: every problem, sorted, and the compiled model if no error."""

    diagnostics: list[Diagnostic]
    model: CompiledModel | None
    source: SourceModel | None

    @property
    def ok(self) -> bool:
        return self.model is not None

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity == "error"]

    @property
    def warnings(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity == "warning"]


class IncrementalCheck:
    """Checks one model again and again (the studio's working copy after each edit), doing again
    only what the change can change, as a language server does: a swimlane whose text did not
    change is not parsed again (`LaneCache`), its nodes and graph are not checked again, and its
    expressions only when something they can name changed (`CheckMemo`). `check` gives what
    `check_model` gives for the same files (tests/test_incremental_check.py holds it to that
    after every edit of random sequences)."""

    def __init__(self) -> None:
        self.lanes = LaneCache()
        self.memo = CheckMemo()

    def check(self, path: str | Path, deployment: str | Path | None = None,
              files: Mapping[str, bytes | Unreadable] | None = None) -> CheckResult:
        return check_model(path, deployment, files, incremental=self)


def check_model(path: str | Path, deployment: str | Path | None = None,
                files: Mapping[str, bytes | Unreadable] | None = None,
                incremental: IncrementalCheck | None = None) -> CheckResult:
    """Check the model at `path` (a folder or one file); `deployment` overrides its deployment file.

    `files` (path relative to the folder -> content) checks those files as the folder `path`
    instead of what is on disk (the studio's working copy); messages name them as on disk. A file
    that could not be read is there as `Unreadable` (`umlbot.compiler.source.read_model_folder` reads a
    folder so): it is reported as `umlbot check` reports it. `incremental`: what the last check of
    the same model kept (`IncrementalCheck.check`); the result is the same.
    """
    diagnostics = Diagnostics()
    source: SourceModel | None = None
    model: CompiledModel | None = None
    # A compile makes many small objects and no reference cycles worth collecting: without the
    # cyclic collector walking the growing heap, 10 000 nodes compile about a third faster.
    collecting = gc.isenabled()
    gc.disable()
    try:
        if incremental is None:
            source = load_source(path, diagnostics, deployment, files)
            model = check_source(source, diagnostics)
        else:
            incremental.lanes.generation()
            source = load_source(path, diagnostics, deployment, files, incremental.lanes)
            model = check_source(source, diagnostics, incremental.memo)
    except ModelError as exc:
        diagnostics.add_model_error(exc)
        model = None
    finally:
        if collecting:
            gc.enable()
    if diagnostics.has_errors:
        model = None
    return CheckResult(diagnostics.sorted(), model, source)


def compile_model(path: str | Path, deployment: str | Path | None = None) -> CompiledModel:
    """The compiled model, or `ModelErrors` listing every problem of the model."""
    result = check_model(path, deployment)
    if result.model is None:
        raise ModelErrors(result.diagnostics)
    return result.model
