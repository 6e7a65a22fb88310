"""Reading the user's files (model files, deployments, tracks, ACLs) with one-line errors.

Every reader of a user's file needs the same things: an unreadable, too large, binary or non-UTF-8
file named in one clear line instead of a traceback — a bad byte at its `file:line:col`, the same
for model files (`umlbot.compiler.source`) and the small files here — and a YAML syntax error as
`file:line:col:` with the problem in one line. There is one YAML reader in umlbot, the compiler's
positioned reader (`umlbot.base.yamlsrc`: libyaml events, YAML 1.2 core schema, size and depth
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
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from umlbot.base.errors import ConfigError, ModelError, UmlbotError

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


class WriteError(UmlbotError, OSError):
    """Writing a set of files failed at `path` (`cause`, in words by `problem`): none of them
    changed, except those in `left`, which could not be put back as they were."""

    def __init__(self, path: Path, cause: OSError, left: Sequence[Path] = ()) -> None:
        super().__init__(cause.errno, os_problem(cause, f"the folder {path.parent}"), str(path))
        self.path = path
        self.cause = cause
        self.left = list(left)

    def __str__(self) -> str:
        text = f"cannot write {self.path}: {self.strerror}"
        if self.left:
            text += f"; {', '.join(map(str, self.left))} could not be put back as they were"
        return text


def os_problem(exc: OSError, folder: str = "the folder") -> str:
    """Why a write into `folder` (its name in the message) failed, in words: "the disk is full",
    "the folder F is read-only (…)", else the system's own words."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return "the disk is full"
    if exc.errno == errno.EROFS:
        return f"{folder} is read-only (read-only file system)"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return f"{folder} is read-only (permission denied)"
    return exc.strerror or str(exc)


def write_atomically(path: Path, data: bytes) -> None:
    """Write `data` to `path` so that a reader never sees half a file and a failed write keeps
    the previous one (`write_files_atomically` of one file)."""
    write_files_atomically({path: data})


def write_files_atomically(changes: Mapping[Path, bytes | None]) -> None:
    """Write (bytes) or remove (None) every file of `changes`, all or none: each new content goes
    to a temporary file in its own folder first (written and fsynced), and only when all are there
    are they renamed into place, each old file kept under a hard link beside it until all are in
    place. A failure before the renames (a full disk, a read-only folder) changes nothing; a
    failure among them puts back the files already replaced. Raises `WriteError` naming the file
    and the problem in words; its `left` names any file that could not be put back.

    Missing folders are made (and removed again on failure); a file in their place is
    `NotADirectoryError`. A file keeps the mode of the one it replaces, else gets an ordinary
    file's (0666 less the umask; mkstemp's is 0600)."""
    staged: list[tuple[Path, str | None]] = []  # (target, its temporary file; None: a removal)
    made: list[Path] = []  # folders made for the new files
    path = Path()
    try:
        for path, data in changes.items():
            if data is not None:
                made += _make_folders(path.parent)
                staged.append((path, _stage(path, data)))
            else:
                staged.append((path, None))
    except OSError as exc:
        _discard([tmp for _, tmp in staged], made)
        raise WriteError(path, exc) from exc
    done: list[tuple[Path, _Kept]] = []
    try:
        for index, (path, tmp) in enumerate(staged):
            kept = _keep(path)
            try:
                if tmp is not None:
                    os.replace(tmp, path)
                    staged[index] = (path, None)
                elif kept.link is not None or kept.data is not None:
                    os.unlink(path)
            except OSError:
                _forget(kept)
                raise
            done.append((path, kept))
    except OSError as exc:
        left = _put_back(done)
        _discard([tmp for _, tmp in staged], made)
        raise WriteError(path, exc, left) from exc
    for _, kept in done:
        _forget(kept)
    for folder in {p.parent for p in changes}:
        _fsync_folder(folder)


class _Kept:
    """The file a write replaces, kept until every file of the set is in place: a hard link beside
    it (`link`), else its bytes (a file system without hard links); neither when there was none."""

    def __init__(self, link: str | None = None, data: bytes | None = None, mode: int | None = None) -> None:
        self.link = link
        self.data = data
        self.mode = mode


def _keep(path: Path) -> _Kept:
    if not os.path.lexists(path):
        return _Kept()
    link = str(path.with_name(f".{path.name}.{os.urandom(4).hex()}.old"))
    try:
        os.link(path, link, follow_symlinks=False)
        return _Kept(link=link)
    except OSError:  # no hard links here: keep the bytes
        return _Kept(data=path.read_bytes(), mode=path.stat().st_mode & 0o777)


def _forget(kept: _Kept) -> None:
    if kept.link is not None:
        with contextlib.suppress(OSError):
            os.unlink(kept.link)


def _put_back(done: list[tuple[Path, _Kept]]) -> list[Path]:
    """Undo the renames made so far (newest first); the files that could not be put back."""
    left: list[Path] = []
    for path, kept in reversed(done):
        try:
            if kept.link is not None:
                os.replace(kept.link, path)
            elif kept.data is not None:
                tmp = _stage(path, kept.data, kept.mode)
                os.replace(tmp, path)
            else:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(path)
        except OSError:
            left.append(path)
    return left


def _make_folders(folder: Path) -> list[Path]:
    """Make `folder` and its missing parents; the ones made, outermost first."""
    missing: list[Path] = []
    for parent in (folder, *folder.parents):
        if parent.exists():
            if not parent.is_dir():
                raise NotADirectoryError(errno.ENOTDIR, f"{parent} is not a folder")
            break
        missing.append(parent)
    for parent in reversed(missing):
        parent.mkdir()
    return list(reversed(missing))


def _stage(path: Path, data: bytes, mode: int | None = None) -> str:
    """`data` in a new temporary file beside `path`, written and fsynced; its name."""
    import tempfile  # here: with shutil, bz2 and lzma about 0.3 MB that a service (which only
    # reads its deployment) never needs (docs/performance.md, "Memory")

    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if mode is None:
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
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return tmp


def _discard(temporary: list[str | None], made: list[Path]) -> None:
    for tmp in temporary:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    for folder in reversed(made):  # innermost first; only if still empty
        with contextlib.suppress(OSError):
            folder.rmdir()


def _fsync_folder(folder: Path) -> None:
    """Make the renames in `folder` durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


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
    from umlbot.base.yamlsrc import to_python

    return to_python(load_yaml_node(text, source, error))


def load_yaml_node(text: str, source: str, error: type[UmlbotError] = ConfigError) -> Any:
    """The positioned tree of a YAML document (`umlbot.base.yamlsrc`; None when empty), for readers
    that name the `file:line:col` of a value in their errors (`where`); errors as `load_yaml`."""
    from umlbot.base.diagnostics import Diagnostics
    from umlbot.base.yamlsrc import parse_yaml

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
    from umlbot.base.yamlsrc import locate

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
