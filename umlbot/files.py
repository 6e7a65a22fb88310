"""Reading the user's small text files (deployments, tracks, ACLs) with one-line errors.

Every reader of a user's file needs the same two things: an unreadable, binary or non-UTF-8 file
named in one clear line instead of a traceback, and a YAML syntax error as `file:line:col:` with
the problem in one line. There is one YAML reader in umlbot, the compiler's positioned reader
(`compiler.yamlsrc`: libyaml events, YAML 1.2 core schema, size and depth limits); `load_yaml`
puts it behind the same one-line errors for the small files.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from umlbot.errors import ConfigError, ModelError, UmlbotError


def read_text(path: str | Path, what: str, error: type[UmlbotError] = ConfigError) -> str:
    """The UTF-8 text of `path`; raises `error` ("cannot read <what> <path>: <why>") otherwise."""
    file = Path(path)
    try:
        return file.read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"cannot read {what} {file}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise error(f"cannot read {what} {file}: not UTF-8 text (byte {exc.start})") from exc


def load_yaml(text: str, source: str, error: type[UmlbotError] = ConfigError) -> Any:
    """The plain Python value of a YAML document (None when empty).

    A syntax error, a duplicate key or an over-large document raises `error` with one line,
    `source:line:col: not valid YAML: problem`.
    """
    from compiler.diagnostics import Diagnostics
    from compiler.yamlsrc import parse_yaml, to_python

    diagnostics = Diagnostics()
    try:
        node = parse_yaml(text, source, diagnostics)
    except ModelError as exc:
        problem = " ".join(exc.message.removeprefix("invalid YAML: ").split())
        raise error(f"{exc.file}:{exc.line}:{exc.column}: not valid YAML: {problem}") from None
    for item in diagnostics.errors:
        where = item.location
        raise error(f"{where.file}:{where.line}:{where.column}: not valid YAML: {item.message}")
    return to_python(node)
