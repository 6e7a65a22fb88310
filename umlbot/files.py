"""Reading the user's small text files (deployments, tracks, ACLs) with one-line errors.

Every reader of a user's file needs the same two things: an unreadable, binary or non-UTF-8 file
named in one clear line instead of a traceback, and a YAML syntax error as `file:line:col:` with
the problem in one line (ruamel's own message spans several lines with a source excerpt).
"""

from __future__ import annotations

from pathlib import Path

from umlbot.errors import ConfigError, UmlbotError


def read_text(path: str | Path, what: str, error: type[UmlbotError] = ConfigError) -> str:
    """The UTF-8 text of `path`; raises `error` ("cannot read <what> <path>: <why>") otherwise."""
    file = Path(path)
    try:
        return file.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"cannot read {what} {file}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise error(f"cannot read {what} {file}: not UTF-8 text (byte {exc.start})") from exc


def yaml_error(source: str, exc: Exception) -> str:
    """A YAML syntax error as one line, `source:line:col: not valid YAML: problem`."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark is not None else source
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or str(exc)
    return f"{where}: not valid YAML: {' '.join(str(problem).split())}"
