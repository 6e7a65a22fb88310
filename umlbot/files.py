"""Reading the user's files (model files, deployments, tracks, ACLs) with one-line errors.

Every reader of a user's file needs the same things: an unreadable, too large, binary or non-UTF-8
file named in one clear line instead of a traceback — a bad byte at its `file:line:col`, the same
for model files (`compiler.source`) and the small files here — and a YAML syntax error as
`file:line:col:` with the problem in one line. There is one YAML reader in umlbot, the compiler's
positioned reader (`compiler.yamlsrc`: libyaml events, YAML 1.2 core schema, size and depth
limits); `load_yaml` puts it behind the same one-line errors for the small files.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import stat
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from umlbot.errors import ConfigError, ModelError, UmlbotError

#: the largest file a user gives umlbot to read (a model file, a deployment, a track).
MAX_FILE_BYTES = 5_000_000


def too_large(size: int) -> str | None:
    """The problem with a file of `size` bytes, or None when it is not too large."""
    return f"file too large ({size} bytes, at most {MAX_FILE_BYTES})" if size > MAX_FILE_BYTES else None


_SPECIAL = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
            (stat.S_ISBLK, "a block device"))


def file_problem(status: os.stat_result) -> str | None:
    """Why a file with this `stat` is not read (too large; a FIFO or a device, whose reading
    could wait for ever), or None. A folder is left to the read's own error ("Is a directory")."""
    for test, name in _SPECIAL:
        if test(status.st_mode):
            return f"not a regular file ({name})"
    return too_large(status.st_size)


def write_atomically(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file in the same folder and a rename, so that a
    reader never sees half a file and a failed write keeps the previous one. Missing folders are
    made; a file in their place is `NotADirectoryError`. The file keeps the mode of the one it
    replaces, else gets an ordinary file's (0666 less the umask; mkstemp's is 0600)."""
    for folder in (path.parent, *path.parent.parents):
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, f"{folder} is not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        try:
            mode = path.stat().st_mode & 0o777
        except OSError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def byte_position(data: bytes, offset: int) -> tuple[int, int]:
    """1-based (line, column) of byte `offset`; the column counts the characters before it (the
    bytes before the first bad one are valid UTF-8)."""
    line_start = data.rfind(b"\n", 0, offset) + 1
    before = data[line_start:offset].decode("utf-8", "replace")
    return data.count(b"\n", 0, offset) + 1, len(before) + 1


def decode_utf8(data: bytes, shown: str) -> str:
    """The UTF-8 text of a file's bytes; `ModelError` at the line and column of the first bad byte
    ("not UTF-8 text: byte 0xff: invalid start byte") otherwise."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, column = byte_position(data, exc.start)
        raise ModelError(f"not UTF-8 text: byte 0x{data[exc.start]:02x}: {exc.reason}",
                         shown, line, column) from None


def read_text(path: str | Path, what: str, error: type[UmlbotError] = ConfigError) -> str:
    """The UTF-8 text of `path`; raises `error` otherwise, in one line: "cannot read <what>
    <path>: <why>", or "<path>:<line>:<col>: cannot read <what>: not UTF-8 text: ..." at the
    first bad byte."""
    file = Path(path)
    try:
        problem = file_problem(file.stat())
        if problem is not None:
            raise error(f"cannot read {what} {file}: {problem}")
        data = file.read_bytes()
    except OSError as exc:
        raise error(f"cannot read {what} {file}: {exc.strerror or exc}") from exc
    try:
        return decode_utf8(data, str(file))
    except ModelError as exc:
        raise error(f"{exc.file}:{exc.line}:{exc.column}: cannot read {what}: {exc.message}") from None


def _not_json(constant: str) -> Any:
    raise ValueError(f"{constant} is not JSON (JSON numbers are finite)")


def _finite_float(text: str) -> float:
    number = float(text)
    if math.isinf(number):
        raise ValueError(f"number out of range: {text[:40]}")
    return number


def loads_json(text: str, finite: bool = False) -> Any:
    """The value of a JSON text. Besides the decoder's own `json.JSONDecodeError` (with its
    position), what the decoder refuses beyond syntax is a `ValueError` with a message of ours:
    nesting too deep for it (5 000 `[` in a row, never its `RecursionError`), and an integer longer
    than Python converts ("integer too long: more than 4300 digits"; Python's own message tells
    the sender to call `sys.set_int_max_str_digits()`, which is no advice for a peer on the wire).

    With `finite`, the decoder's extensions `NaN`, `Infinity` and `-Infinity`, and a number too
    large for a float (`1e400`), are such `ValueError`s too: the value is then JSON as RFC 8259
    and a browser know it. Without it they parse (the services answer them with `bad_args`).
    """
    try:
        if finite:
            return json.loads(text, parse_constant=_not_json, parse_float=_finite_float)
        return json.loads(text)
    except RecursionError:
        raise ValueError("nested too deeply") from None
    except json.JSONDecodeError:
        raise
    except ValueError as exc:
        if "integer string conversion" not in str(exc):
            raise
        raise ValueError(f"integer too long: more than {sys.get_int_max_str_digits()} digits") from None


def load_yaml(text: str, source: str, error: type[UmlbotError] = ConfigError) -> Any:
    """The plain Python value of a YAML document (None when empty).

    A syntax error, a duplicate key or an over-large document raises `error` with one line,
    `source:line:col: not valid YAML: problem`.
    """
    from compiler.yamlsrc import to_python

    return to_python(load_yaml_node(text, source, error))


def load_yaml_node(text: str, source: str, error: type[UmlbotError] = ConfigError) -> Any:
    """The positioned tree of a YAML document (`compiler.yamlsrc`; None when empty), for readers
    that name the `file:line:col` of a value in their errors (`where`); errors as `load_yaml`."""
    from compiler.diagnostics import Diagnostics
    from compiler.yamlsrc import parse_yaml

    diagnostics = Diagnostics()
    try:
        node = parse_yaml(text, source, diagnostics)
    except ModelError as exc:
        problem = " ".join(exc.message.removeprefix("invalid YAML: ").split())
        raise error(f"{exc.file}:{exc.line}:{exc.column}: not valid YAML: {problem}") from None
    for item in diagnostics.errors:
        where_ = item.location
        raise error(f"{where_.file}:{where_.line}:{where_.column}: not valid YAML: {item.message}")
    return node


def where(source: str, root: Any, path: Sequence[int | str] = ()) -> str:
    """`source:line:col` of the value at `path` in a positioned YAML tree (as deep as the path is
    written); just `source` without a tree (a plain-text or JSON file)."""
    if root is None:
        return source
    from compiler.source import locate

    loc = locate(root, tuple(path))
    return f"{loc.file}:{loc.line}:{loc.column}"


def validation_problem(errors: Sequence[Mapping[str, Any]], source: str, root: Any, what: str,
                       prefix: Sequence[int | str] = (), every: bool = False) -> str:
    """One line for pydantic's errors: `file:line:col: <what>: path: message` of the first, and how
    many more there are (a whole list of them is no help when the file is of the wrong kind), or
    with `every` the others too, each with its `(line:col)`. `prefix` is where the validated value
    sits in the file."""

    def problem(error: Mapping[str, Any]) -> str:
        dotted = ".".join(str(p) for p in error["loc"])
        return f"{dotted}: {error['msg']}" if dotted else str(error["msg"])

    def at(error: Mapping[str, Any]) -> str:
        return where(source, root, (*prefix, *error["loc"]))

    first, rest = errors[0], errors[1:]
    text = f"{at(first)}: {what}: {problem(first)}"
    if every:
        for error in rest:
            position = at(error).removeprefix(source + ":")
            text += f"; {problem(error)}" + (f" ({position})" if root is not None else "")
    elif rest:
        text += f" (and {len(rest)} more problem{'s' if len(rest) > 1 else ''})"
    return text
