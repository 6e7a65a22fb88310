"""The studio's working copy of one model folder: edits, undo/redo, checks, saving, files on disk.

The working copy is the model's files (relative path -> bytes) as the page has edited them; the
compiler checks it in memory (`check_model(root, files=…)`; after an edit incrementally,
`IncrementalCheck`, with the same result), so its messages are `umlbot check`'s, naming the files
as on disk; a model file that cannot be read (no permission, not a file, too large) is in it
as `Unreadable`, reported as `umlbot check` reports it, never edited and never written. Saving
writes only the files that differ, all or none (`write_files_atomically`: temp files in their
folders, then renames, the old files kept until all are in place), and only inside the model
folder; a failed save says why in words and leaves the files as they were.

`disk` is what the studio last saw on disk (read, or written by itself), so the invariant the page
relies on is: every file of the working copy equals the disk's or is unsaved (`dirty`). A file
changed on disk is taken in when the working copy has not changed it; otherwise it is a conflict
the user resolves (reload, or save with force, which writes what the page shows). Positions the
page chose live in `.umlbot-studio.json`, which the compiler never reads.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import secrets
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from umlbot.base.errors import ModelError
from umlbot.base.files import (
    WriteError,
    decode_utf8,
    file_problem,
    loads_json,
    os_problem,
    write_files_atomically,
)
from umlbot.compiler.api import CheckResult, IncrementalCheck
from umlbot.compiler.source import ACTIVITIES_DIR, MODEL_FILE, Unreadable, read_model_folder
from umlbot.studio.edit import (
    EditError,
    Rename,
    apply_ops,
    lane_files,
    parse_ops,
    rename_positions,
    takes_lanes,
)
from umlbot.studio.model_view import (
    LaneViews,
    attribute,
    deployment_fields,
    diagnostic_view,
    node_index,
    source_view,
)

LAYOUT_FILE = ".umlbot-studio.json"
#: unsaved edits kept when the studio quits; the next start offers to restore or discard them.
RECOVERY_FILE = ".umlbot-studio-recovery.json"
HISTORY = 200


class Conflict(Exception):
    """A request that does not fit the working copy's state (HTTP 409); `body` is the answer."""

    def __init__(self, body: dict[str, Any]) -> None:
        super().__init__(body.get("error", "conflict"))
        self.body = body


class SaveFailed(Exception):
    """A save that could not write its files (HTTP `status`: 507 for a full disk, 403 for a
    read-only folder, else 500); `body` is the answer, its `error` in words."""

    def __init__(self, status: int, body: dict[str, Any]) -> None:
        super().__init__(body["error"])
        self.status = status
        self.body = body

    @staticmethod
    def status_of(exc: OSError) -> int:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            return 507
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            return 403
        return 500


STARTER: dict[str, str] = {
    MODEL_FILE: """\
# A robot car: two L298N motor channels, a sonar on a servo (see docs/model-format.md).
name: {name}
components:
  RaspberryPI: {kind: system}
  LeftActuator: {kind: actuator, ports: {drive: enabled}}
  RightActuator: {kind: actuator, ports: {drive: enabled}}
  Sensor: {kind: actuator, ports: {pointing: angle}}
  DistanceRead: {kind: sensor, ports: {range: value}}
""",
    "deployment.yaml": """\
# Which part realises each component, and its wiring (BCM pins).
driver: auto                   # lgpio on a Raspberry Pi 5, pigpio where pigpiod runs
components:
  RaspberryPI: {impl: raspberrypi, settings: {pins: []}}
  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}
  RightActuator: {impl: l298n, settings: {in1: 24, in2: 25}}
  Sensor: {impl: servo, settings: {gpio: 18}}
  DistanceRead: {impl: hcsr04, settings: {trigger: 8, echo: 7}}
""",
    f"{ACTIVITIES_DIR}/main.yaml": """\
# The main program: the RaspberryPI lane starts when the robot starts.
lane: RaspberryPI
nodes:
  - {id: start, kind: start}
  - {id: end, kind: end}
""",
}


#: a model file's content in the working copy: its bytes, or why it could not be read.
Content = bytes | Unreadable


def model_files(root: Path) -> dict[str, Content]:
    """The files of the model folder `root` that the compiler reads, by relative path, as the
    compiler reads them (`umlbot.compiler.source.read_model_folder`): one it cannot read is there as
    `Unreadable`, so the check names it as `umlbot check` does, and saving leaves it alone."""
    return read_model_folder(root)


def read_layout(root: Path) -> tuple[dict[str, Any], str | None]:
    """The positions saved in `root`'s layout file, and what was wrong with it (one line, with
    `file:line:col` where there is one) when it could not be read: the page then starts without
    them, and saving rewrites the file. No file is no problem."""
    path = root / LAYOUT_FILE
    try:
        problem = file_problem(path.stat())
        if problem is not None:
            return {}, f"{path}: {problem}"
        text = decode_utf8(path.read_bytes(), str(path))
    except FileNotFoundError:
        return {}, None
    except OSError as exc:
        return {}, f"cannot read {path}: {exc.strerror or exc}"
    except ModelError as exc:
        return {}, f"{exc.file}:{exc.line}:{exc.column}: {exc.message}"
    try:
        data = loads_json(text)
    except json.JSONDecodeError as exc:
        return {}, f"{path}:{exc.lineno}:{exc.colno}: not valid JSON: {exc.msg}"
    except ValueError as exc:  # nested too deeply, an integer too long
        return {}, f"{path}: not valid JSON: {exc}"
    if not isinstance(data, dict):
        return {}, f"{path}:1:1: not a layout (a JSON object with 'positions')"
    return data, None


def shown(text: str, limit: int = 80) -> str:
    """`text` quoted for a message, cut to `limit` characters (a 5 000-character name sent by a
    client is not worth repeating whole)."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + f"… ({len(text)} characters)"


def safe_path(root: Path, rel: str) -> Path:
    """`root / rel`, refused (ValueError) unless it stays inside `root`, symlinks resolved; a name
    the system refuses (too long, a NUL byte) is refused the same way."""
    if not isinstance(rel, str):
        raise ValueError(f"a path inside the model folder is a string, not {type(rel).__name__}")
    pure = PurePosixPath(rel)
    if pure.is_absolute() or ".." in pure.parts or not pure.parts or "\\" in rel:
        raise ValueError(f"{shown(rel)} is not a path inside the model folder")
    try:
        real_root = root.resolve()
        target = (root / pure).resolve()
    except (OSError, ValueError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ValueError(f"{shown(rel)} is not a path inside the model folder ({why})") from None
    if not target.is_relative_to(real_root) or target == real_root:
        raise ValueError(f"{shown(rel)} is not a path inside the model folder")
    return target


def write_inside(root: Path, files: dict[str, bytes | None]) -> None:
    """Write (bytes) or remove (None) the files `files` (relative paths) inside `root`, all or
    none (`umlbot.base.files.write_files_atomically`), refused (ValueError) unless every path stays
    inside `root`. Raises `WriteError` when the disk refuses."""
    write_files_atomically({safe_path(root, rel): data for rel, data in files.items()})


def _differ(a: dict[str, Content], b: dict[str, Content]) -> list[str]:
    """The paths whose content differs between two sets of files (or that only one has)."""
    return sorted(rel for rel in set(a) | set(b) if a.get(rel) != b.get(rel))


@dataclass
class State:
    """One state of the working copy (what undo and redo go back and forth between)."""

    files: dict[str, Content]
    #: the renames that going back to this state undoes: the layout's positions follow them
    #: (positions are not edits, but a position kept under a name that is gone is lost)
    renames: list[Rename] = field(default_factory=list)


@dataclass
class Workspace:
    """The working copy of the model folder `root` (as the user named it: messages show it)."""

    root: Path
    token: str = field(default_factory=lambda: secrets.token_urlsafe(24))
    version: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        #: why the layout file could not be read (None when it was, or there is none).
        self.layout_problem: str | None = None
        self.disk = model_files(self.root)  # the files as the studio last saw them on disk
        self.files = dict(self.disk)
        self.layout_disk = self._read_layout()
        self.layout: dict[str, Any] = json.loads(json.dumps(self.layout_disk))
        self.undo_stack: list[State] = []
        self.redo_stack: list[State] = []
        #: files changed on disk while the working copy had changed them too (the user decides)
        self.conflicts: set[str] = set()
        self.result: CheckResult | None = None
        #: checks the working copy after each edit doing again only what the edit changed (its
        #: answer is `check_model`'s for the same files)
        self.checker = IncrementalCheck()
        self.lane_views = LaneViews()  # the page's views of the swimlanes the edit left alone
        self.answer_cache: dict[str, Any] = {}
        self._lanes_memo: dict[str, tuple[bytes, bool]] = {}
        #: unsaved edits a previous studio kept when it quit (None: none, or decided).
        self.recovery: dict[str, Any] | None = self._read_recovery()
        self.check()

    # --- reading -----------------------------------------------------------------------------------

    def _read_layout(self) -> dict[str, Any]:
        layout, self.layout_problem = read_layout(self.root)
        return layout

    @property
    def empty(self) -> bool:
        return not self.files

    @property
    def dirty(self) -> bool:
        return self.files != self.disk or self.layout != self.layout_disk

    def hello(self) -> dict[str, Any]:
        """The `edit` part of the socket's hello."""
        return {"token": self.token, "root": str(self.root), "empty": self.empty, "dirty": self.dirty,
                "version": self.version, "layout": self.layout, "conflict": self.live_conflicts(),
                "recovery": self.recovery_view(), **self.answer_cache}

    def texts(self) -> dict[str, str]:
        """The files' texts (a bad byte shown as U+FFFD); a file that cannot be read is left out
        (the diagnostics name it)."""
        return {rel: data.decode("utf-8", "replace") for rel, data in sorted(self.files.items())
                if isinstance(data, bytes)}

    def readable_files(self) -> dict[str, bytes]:
        """The files whose bytes the working copy holds (what a run copies)."""
        return {rel: data for rel, data in self.files.items() if isinstance(data, bytes)}

    # --- checking ------------------------------------------------------------------------------------

    def check(self, result: CheckResult | None = None) -> dict[str, Any]:
        """Check the working copy with the compiler (unless `result` is that check already); the
        page's answer (model view, diagnostics)."""
        if result is None:
            result = self.checker.check(self.root, files=self.files)
        self.result = result
        if result.source is not None:
            self.lane_views.keep_only(result.source)
        index = node_index(result.source, self.lane_views) if result.source is not None else {}
        fields = deployment_fields(result.source) if result.source is not None else {}
        diagnostics = [attribute(diagnostic_view(d), self._relative(d.location.file), index, fields)
                       for d in result.diagnostics]
        self.answer_cache = {
            "model": source_view(result.source, self.lane_views)
            if result.source is not None and self.files else None,
            # where the page may offer to add a swimlane (besides a new file of its own)
            "lane_files": self._lane_files(),
            "compiled": result.model is not None,
            # an empty folder is offered a starter, not told that it is no model
            "diagnostics": diagnostics if self.files else [],
        }
        return self.answer()

    def _lane_files(self) -> list[str]:
        """The files `add_lane` can add a swimlane to (`takes_lanes`); a file is read again only
        when it changed (an edit changes one file: the others are not parsed again for it)."""
        memo: dict[str, tuple[bytes, bool]] = {}
        for rel in lane_files(self.files):
            data = self.files[rel]
            if not isinstance(data, bytes):
                continue
            seen = self._lanes_memo.get(rel)
            if seen is None or seen[0] != data:
                try:
                    seen = (data, takes_lanes(rel, data.decode("utf-8")))
                except UnicodeDecodeError:
                    seen = (data, False)
            memo[rel] = seen
        self._lanes_memo = memo
        return [rel for rel, (_, takes) in memo.items() if takes]

    def _relative(self, shown: str) -> str | None:
        try:
            return Path(shown).relative_to(self.root).as_posix()
        except ValueError:
            return None

    def answer(self, changed: list[str] | None = None, renames: list[Rename] | None = None) -> dict[str, Any]:
        """The answer to the page; `renamed`: what this step renamed (an undo of a rename names it
        back), so that the page keeps the renamed thing selected."""
        return {"version": self.version, **self.answer_cache, "changed": changed or [],
                "dirty": self.dirty,
                "renamed": [{"kind": r.kind, "old": r.old, "new": r.new, "lane": r.lane}
                            for r in renames or []]}

    # --- editing -------------------------------------------------------------------------------------

    def _expect(self, version: Any) -> None:
        if version != self.version:
            raise Conflict({"error": f"the model changed meanwhile (version {self.version}, the page "
                                     f"has {version}): reload it", "version": self.version})

    def edit(self, version: Any, raw_ops: Any) -> dict[str, Any]:
        """Apply a batch of operations (all or none) and check the result once."""
        self._expect(version)
        ops = parse_ops(raw_ops)
        layout_ops = [op for op in ops if op.op == "set_layout"]
        text_ops = [op for op in ops if op.op != "set_layout"]
        texts: dict[str, str | None] = {}
        for rel, data in self.files.items():
            try:
                texts[rel] = data.decode("utf-8") if isinstance(data, bytes) else None
            except UnicodeDecodeError:
                texts[rel] = None
            # None: there but unreadable, which an edit refuses to change; the compiler reports it
        renames: list[Rename] = []
        changes = apply_ops(texts, text_ops, renames) if text_ops else {}
        for rel in changes:  # e.g. a link that leads outside: refused now, not at the next save
            try:
                safe_path(self.root, rel)
            except ValueError as exc:
                raise EditError(f"{exc}: the studio writes only inside {self.root}") from None
        files = dict(self.files)
        for rel, text in changes.items():
            if text is None:
                files.pop(rel, None)
            else:
                files[rel] = text.encode("utf-8")
        result = self.checker.check(self.root, files=files) if changes else None
        if result is not None:
            self._refuse_names_the_compiler_refuses(text_ops, result)  # before anything changes
        for op in layout_ops:
            diagram = op.diagram or "components"
            positions = op.positions or {}
            bucket = self.layout.setdefault("positions", {}).setdefault(diagram, {})
            for key, value in positions.items():
                if value is None:
                    bucket.pop(key, None)
                else:
                    bucket[key] = [round(float(v), 1) for v in value]
        self.version += 1
        if result is None:
            return self.answer()
        moved = rename_positions(self.layout, renames)
        self.undo_stack.append(State(dict(self.files), [r.reverse() for r in reversed(renames)]))
        del self.undo_stack[:-HISTORY]
        self.redo_stack.clear()
        self.files = files
        self.check(result)
        return self._with_layout(self.answer(sorted(changes), renames), moved)

    def _refuse_names_the_compiler_refuses(self, ops: list[Any], result: CheckResult) -> None:
        """A swimlane or component name given by an edit (new or renamed) that the compiler
        refuses (e.g. `msleep`, a builtin, as a swimlane) is refused at its field with the
        compiler's own line (`umlbot check`'s): the compiler decides what a name may be, the studio
        has no rule of its own. Nothing changes then. (A node id is checked only for being a plain
        name, which its YAML text needs; a new node's other problems, such as the call it does not
        have yet, are the diagnostics of an unfinished node, not a refusal.)"""
        source = result.source
        if source is None:
            return
        for op in ops:
            named = {"rename_lane": ("new_name", op.new_name, "lane"), "add_lane": ("lane", op.lane, "lane"),
                     "rename_component": ("new_name", op.new_name, "component"),
                     "add_component": ("name", op.name, "component")}.get(op.op)
            if named is None or not isinstance(named[1], str):
                continue
            field_name, name, what = named
            # where the name is written: an error there is about the name itself (a pin wired
            # twice by a new component is its settings' problem, shown at that field instead)
            if what == "lane":
                at = {lane.loc for lane in source.lanes if lane.name == name}
            else:
                at = {source.components[name].loc} if name in source.components else set()
            for d in result.diagnostics:
                if d.severity == "error" and d.location in at:
                    raise EditError(d.message, fields={field_name: str(d)})

    def undo(self) -> dict[str, Any]:
        return self._step(self.undo_stack, self.redo_stack, "undo")

    def redo(self) -> dict[str, Any]:
        return self._step(self.redo_stack, self.undo_stack, "redo")

    def _step(self, source: list[State], other: list[State], what: str) -> dict[str, Any]:
        if not source:
            raise Conflict({"error": f"nothing to {what}", "version": self.version})
        state = source.pop()
        other.append(State(dict(self.files), [r.reverse() for r in reversed(state.renames)]))
        moved = rename_positions(self.layout, state.renames)
        changed = _differ(state.files, self.files)
        self.files = state.files
        self.version += 1
        self.check()
        return self._with_layout(self.answer(changed, state.renames), moved)

    def _with_layout(self, answer: dict[str, Any], moved: bool) -> dict[str, Any]:
        """The answer, with the layout when a rename moved positions to the new names."""
        return {**answer, "layout": self.layout} if moved else answer

    # --- files on disk -------------------------------------------------------------------------------

    def changed_files(self) -> list[str]:
        """The files the working copy has changed: unsaved (they differ from the disk's)."""
        return _differ(self.files, self.disk)

    def live_conflicts(self) -> list[str]:
        """The conflicts that still stand: a file the working copy no longer changes (an undo or
        an edit made it what the disk holds) is one no more."""
        self.conflicts &= set(self.changed_files())
        return sorted(self.conflicts)

    def save(self, version: Any, force: bool = False) -> dict[str, Any]:
        """Write every changed file, all or none (inside the folder); 409 on a conflict, unless
        `force`: then the disk gets what the page shows. A failed write raises `SaveFailed` with
        the reason in words; the files on disk are then as they were."""
        self._expect(version)
        changed = self.changed_files()
        on_disk = model_files(self.root)
        # changed on disk since the last look, into something else than what the page shows
        moved = {rel for rel in changed if on_disk.get(rel) not in (self.disk.get(rel), self.files.get(rel))}
        conflicts = sorted(moved | set(self.live_conflicts()))
        if conflicts and not force:
            raise Conflict({"error": "changed on disk since it was loaded: " + ", ".join(conflicts),
                            "conflict": conflicts, "version": self.version})
        writes: dict[str, bytes | None] = {}
        for rel in changed:
            data = self.files.get(rel)
            if not isinstance(data, Unreadable):  # an unreadable file is never written over
                writes[rel] = data
        layout = None
        if self.layout != self.layout_disk:
            layout = json.loads(json.dumps(self.layout))
            writes[LAYOUT_FILE] = (json.dumps(self.layout, indent=1, sort_keys=True) + "\n").encode("utf-8")
        try:
            write_inside(self.root, writes)
        except WriteError as exc:
            self._saw(model_files(self.root), changed)  # what is on disk now (all put back, or not)
            raise self._failed(exc) from exc
        for rel in changed:
            if rel in writes:
                self._seen(rel, writes[rel])
        if layout is not None:
            self.layout_disk = layout
        self.conflicts.clear()
        return {"saved": list(writes), "dirty": self.dirty, "version": self.version}

    def _failed(self, exc: WriteError) -> SaveFailed:
        """A save refused by the disk, in words, with the file named relative to the folder."""
        try:
            rel = exc.path.relative_to(self.root.resolve()).as_posix()
        except ValueError:
            rel = str(exc.path)
        folder = PurePosixPath(rel).parent
        where = f"the folder {folder}" if str(folder) != "." else f"the model folder {self.root}"
        text = f"cannot save {rel}: {os_problem(exc.cause, where)}. "
        if exc.left:
            left = ", ".join(p.name for p in exc.left)
            text += f"{left} could not be put back as it was: look at it on disk before saving again"
        else:
            text += "Nothing was saved: the files on disk are as they were, your edits are kept"
        return SaveFailed(SaveFailed.status_of(exc.cause), {"error": text, "message": text, "file": rel,
                                                            "version": self.version, "dirty": self.dirty})

    def _seen(self, rel: str, data: Content | None) -> None:
        """The disk holds `data` at `rel` now (None: no file)."""
        if data is None:
            self.disk.pop(rel, None)
        else:
            self.disk[rel] = data

    def _saw(self, current: dict[str, Content], rels: list[str]) -> None:
        """Record what the disk holds now for `rels` where it is what the studio wrote (a file it
        could not put back after a failed save): a retry must not take its own write for a change
        by someone else."""
        for rel in rels:
            if current.get(rel) == self.files.get(rel):
                self._seen(rel, current.get(rel))

    def reload(self) -> dict[str, Any]:
        """Discard the working copy's edits: take the files on disk."""
        self.disk = model_files(self.root)
        changed = _differ(self.files, self.disk)
        self.files = dict(self.disk)
        self.layout_disk = self._read_layout()
        self.layout = json.loads(json.dumps(self.layout_disk))
        self.undo_stack.clear()
        self.redo_stack.clear()
        self.conflicts.clear()
        self.version += 1
        self.check()
        return self.answer(changed)

    def poll(self) -> list[dict[str, Any]]:
        """Look at the disk; the frames to push to the pages (none when nothing changed).

        Files the working copy has not changed are taken in (`files` frame); files it changed
        otherwise are a conflict (`conflict` frame) until the user reloads or saves with force;
        a file it changed into what the disk holds now is simply saved. Either way `disk` is the
        disk's now, so a file the page shows otherwise stays unsaved whatever is undone meanwhile.
        """
        current = model_files(self.root)
        changed = _differ(current, self.disk)
        if not changed:
            return []
        taken = [rel for rel in changed if self.files.get(rel) == self.disk.get(rel)]
        clashes = [rel for rel in changed if rel not in taken and self.files.get(rel) != current.get(rel)]
        for rel in changed:
            self._seen(rel, current.get(rel))
        frames: list[dict[str, Any]] = []
        if taken:
            for rel in taken:
                data = current.get(rel)
                if data is None:
                    self.files.pop(rel, None)
                else:
                    self.files[rel] = data
            # an undo must not bring back what was replaced on disk
            self.undo_stack.clear()
            self.redo_stack.clear()
            self.version += 1
            self.check()
            frames.append({"type": "files", "reason": "changed on disk", **self.answer(taken)})
        if clashes:
            self.conflicts.update(clashes)
            frames.append({"type": "conflict", "changed": self.live_conflicts(), "version": self.version,
                           "dirty": self.dirty})
        return frames

    # --- unsaved edits when the studio quits ------------------------------------------------------

    def _read_recovery(self) -> dict[str, Any] | None:
        path = self.root / RECOVERY_FILE
        try:
            data = json.loads(path.read_bytes().decode("utf-8"))
        except FileNotFoundError:
            return None
        except (OSError, ValueError):
            return None  # not ours to judge: left as it is on disk
        if not isinstance(data, dict) or not isinstance(data.get("files"), dict):
            return None
        files = data["files"]
        if not all(isinstance(k, str) and (v is None or isinstance(v, str)) for k, v in files.items()):
            return None
        return data

    def recovery_view(self) -> dict[str, Any] | None:
        """What the page says about kept edits: when, which files."""
        if self.recovery is None:
            return None
        return {"time": self.recovery.get("time"), "files": sorted(self.recovery["files"]),
                "layout": self.recovery.get("layout") is not None}

    def keep_unsaved(self) -> Path | None:
        """The studio quits: write the unsaved edits (the changed files' texts, None for a removed
        one, and the layout) into `RECOVERY_FILE` inside the folder, atomically; the model's own
        files are not touched. A recovery file not yet restored or discarded is kept beside it
        under a name with its time. The path written, None when there was nothing unsaved."""
        if not self.dirty:
            return None
        files: dict[str, str | None] = {}
        for rel in self.changed_files():
            data = self.files.get(rel)
            if data is None:
                files[rel] = None
            elif isinstance(data, bytes):
                files[rel] = data.decode("utf-8", "surrogateescape")
        body: dict[str, Any] = {
            "time": time.strftime("%Y-%m-%d %H:%M:%S"),
            "files": files,
            "layout": self.layout if self.layout != self.layout_disk else None,
        }
        path = self.root / RECOVERY_FILE
        if self.recovery is not None and path.exists():
            stamp = re.sub(r"\D", "", str(self.recovery.get("time") or "")) or str(int(time.time()))
            os.replace(path, self.root / f".umlbot-studio-recovery.{stamp}.json")
        text = json.dumps(body, indent=1, sort_keys=True) + "\n"
        write_inside(self.root, {RECOVERY_FILE: text.encode("utf-8")})
        return path

    def recover(self, action: Any) -> dict[str, Any]:
        """`restore`: the kept edits become the working copy's (unsaved: Save writes them; Undo
        goes back to the files on disk); `discard`: forget them. Either way the recovery file
        goes."""
        if self.recovery is None:
            raise Conflict({"error": "there are no kept edits", "version": self.version})
        if action not in ("restore", "discard"):
            raise EditError("'action' is restore or discard")
        changed: list[str] = []
        if action == "restore":
            self.undo_stack.append(State(dict(self.files)))
            self.redo_stack.clear()
            for rel, text in self.recovery["files"].items():
                safe_path(self.root, rel)
                if isinstance(self.files.get(rel), Unreadable):
                    continue  # never over a file that cannot be read
                if text is None:
                    self.files.pop(rel, None)
                else:
                    self.files[rel] = text.encode("utf-8", "surrogateescape")
                changed.append(rel)
            layout = self.recovery.get("layout")
            if isinstance(layout, dict):
                self.layout = layout
            self.version += 1
        with contextlib.suppress(FileNotFoundError):
            safe_path(self.root, RECOVERY_FILE).unlink()
        self.recovery = None
        self.check()
        return {**self.answer(sorted(changed)), "layout": self.layout}

    def new_model(self, name: str | None) -> dict[str, Any]:
        """Write the starter model into an empty folder (and save it)."""
        if not self.empty:
            raise Conflict({"error": "the folder holds a model already", "version": self.version})
        model_name = name or self.root.resolve().name
        if not isinstance(model_name, str) or not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_-]*", model_name):
            shown_name = shown(model_name) if isinstance(model_name, str) else type(model_name).__name__
            raise EditError(f"a model's name is a plain name (letters, digits, _ and -), not {shown_name}",
                            fields={"name": "must be a plain name (letters, digits, _ and -; no spaces)"})
        try:
            self.root.mkdir(exist_ok=True)
        except OSError as exc:
            text = f"cannot make the folder {self.root}: {os_problem(exc, f'the folder {self.root.parent}')}"
            raise SaveFailed(SaveFailed.status_of(exc), {"error": text, "message": text,
                                                         "version": self.version}) from exc
        self.files = {rel: text.replace("{name}", model_name).encode("utf-8")
                      for rel, text in STARTER.items()}
        self.version += 1
        result = self.save(self.version)
        self.undo_stack.clear()
        self.redo_stack.clear()
        self.check()
        return {**self.answer(result["saved"]), "saved": result["saved"]}
