"""The studio's saves against a real disk: all or none (a full disk, a read-only folder, a rename
that fails midway), the reason in words, a retry that saves, and a page never out of step with
the disk without saying so (after any edits, undos, changes on disk and saves)."""

from __future__ import annotations

import errno
import math
import os
import re
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robot_run import CAR_MODEL
from studio_support import Editor, StudioClient, read_frames, snapshot, studio

from umlbot.studio.workspace import Conflict, SaveFailed, Workspace, model_files

MAIN = "activities/main.yaml"
MOTION = "activities/motion.yaml"
#: an edit of each file (main.yaml's first: the files are written in that order)
SPEED: dict[str, Any] = {"op": "set_node", "lane": "RaspberryPI", "id": "set_speed",
                         "fields": {"value": "55"}}
LONG_CALL = "LeftActuator.direction(" + " or ".join(["true"] * 4000) + ")"  # ~32 KB
BACKWARD: dict[str, Any] = {"op": "set_node", "lane": "MoveForward", "id": "left_forward",
                            "fields": {"call": LONG_CALL}}


def _model_snapshot(root: Path) -> dict[str, bytes]:
    """Every file of the folder but a filler (left-over temporary or kept files would show)."""
    return {rel: data for rel, data in snapshot(root).items() if rel != "filler.bin"}


# --- all or none --------------------------------------------------------------------------------


def test_a_rename_that_fails_midway_puts_the_first_file_back_and_a_retry_saves_both(
        car: tuple[Path, Editor], monkeypatch: pytest.MonkeyPatch) -> None:
    root, editor = car
    before = snapshot(root)
    status, answer = editor.post("edit", {"version": 0, "ops": [SPEED, BACKWARD]})
    assert status == 200 and answer["changed"] == [MAIN, MOTION], answer
    rename = os.replace

    def failing(src: Any, dst: Any) -> None:  # the second file's rename fails (an I/O error)
        if str(dst).endswith("motion.yaml"):
            raise OSError(errno.EIO, "Input/output error")
        rename(src, dst)

    monkeypatch.setattr(os, "replace", failing)
    status, failed = editor.post("save", {"version": answer["version"]})
    monkeypatch.undo()
    assert status == 500, failed
    assert failed["error"] == (f"cannot save {MOTION}: Input/output error. Nothing was saved: the files on "
                               "disk are as they were, your edits are kept"), failed
    assert failed["dirty"] is True
    assert snapshot(root) == before  # main.yaml is back; no temporary or kept file is left
    status, saved = editor.post("save", {"version": answer["version"]})
    assert status == 200 and saved["saved"] == [MAIN, MOTION], saved  # no 409 on its own write
    assert LONG_CALL in (root / MOTION).read_text("utf-8")
    assert "value: 55}" in (root / MAIN).read_text("utf-8")


def test_a_file_that_cannot_be_put_back_is_named_and_a_retry_takes_it_as_the_studios_own(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    ws = Workspace(root)
    ws.edit(ws.version, [SPEED, BACKWARD])
    rename = os.replace

    def failing(src: Any, dst: Any) -> None:  # the second rename fails, and so does putting back
        if str(dst).endswith("motion.yaml") or str(src).endswith(".old"):
            raise OSError(errno.EIO, "Input/output error")
        rename(src, dst)

    monkeypatch.setattr(os, "replace", failing)
    with pytest.raises(SaveFailed) as failed:
        ws.save(ws.version)
    monkeypatch.undo()
    assert failed.value.status == 500
    assert "main.yaml could not be put back as it was" in failed.value.body["error"]
    # the studio knows what it wrote: only motion.yaml is unsaved, and the retry is no conflict
    assert ws.changed_files() == [MOTION]
    assert ws.save(ws.version)["saved"] == [MOTION]
    assert model_files(root)[MAIN] == ws.files[MAIN] and model_files(root)[MOTION] == ws.files[MOTION]


def test_a_file_written_on_disk_as_the_page_shows_it_is_no_conflict(tmp_path: Path) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    ws = Workspace(root)
    ws.edit(ws.version, [SPEED])
    mine = ws.files[MAIN]
    assert isinstance(mine, bytes)
    (root / MAIN).write_bytes(mine)  # e.g. the same edit made in another editor, not looked at yet
    assert ws.save(ws.version)["saved"] == [MAIN] and not ws.dirty
    assert ws.poll() == [] and (root / MAIN).read_bytes() == mine


# The studio runs in its own user and mount namespaces (`unshare`, no privileges needed) on a
# small tmpfs holding a copy of the car: a real full disk, a real read-only file system. The test
# sees that folder through /proc/<pid>/root.
ON_TMPFS = ('mount -t tmpfs -o "size=$1" tmpfs "$2" && cp -R "$3"/. "$2"/ '
            '&& if [ "$4" = ro ]; then mount -o remount,ro "$2"; fi && shift 4 && exec "$@"')


@contextmanager
def studio_on_tmpfs(tmp_path: Path, size: str, mode: str) -> Iterator[tuple[Path, StudioClient, int]]:
    """`umlbot studio` on a tmpfs of `size` holding a copy of the car (read-only with mode `ro`):
    the folder as the test sees it, a client for the studio's requests, and the version."""
    folder = tmp_path / "car"
    folder.mkdir()
    prefix = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", ON_TMPFS, "sh", size,
              str(folder), str(CAR_MODEL), mode]
    with studio(["studio", str(folder), "--port", "0"], tmp_path, prefix=prefix) as proc:
        hello = read_frames(proc.url, lambda f: len(f) >= 1)[0]
        yield (Path(f"/proc/{proc.popen.pid}/root{folder}"), StudioClient(proc.url, hello["edit"]["token"]),
               hello["edit"]["version"])


def test_a_full_disk_saves_nothing_says_so_and_the_retry_saves_all(tmp_path: Path) -> None:
    with studio_on_tmpfs(tmp_path, "256k", "rw") as (disk, client, version):
        before = snapshot(disk)
        assert before == snapshot(CAR_MODEL)
        status, answer = client.post("edit", {"version": version, "ops": [SPEED, BACKWARD]})
        assert status == 200 and answer["changed"] == [MAIN, MOTION], answer
        # fill the disk but for room for main.yaml's new text and a page: not for motion.yaml's
        page = os.statvfs(disk).f_frsize
        room = (math.ceil(len(before[MAIN]) / page) + 1) * page
        assert len(before[MOTION]) + len(LONG_CALL) > room + page
        (disk / "filler.bin").write_bytes(b"\0" * (os.statvfs(disk).f_bavail * page - room))
        status, failed = client.post("save", {"version": answer["version"]})
        assert status == 507, failed
        assert failed["error"] == (f"cannot save {MOTION}: the disk is full. Nothing was saved: the files "
                                   "on disk are as they were, your edits are kept"), failed
        assert _model_snapshot(disk) == before  # main.yaml too, and no temporary file is left
        (disk / "filler.bin").unlink()
        status, saved = client.post("save", {"version": answer["version"]})
        assert status == 200 and saved["saved"] == [MAIN, MOTION] and not saved["dirty"], saved
        assert LONG_CALL in (disk / MOTION).read_text("utf-8")
        assert "value: 55}" in (disk / MAIN).read_text("utf-8")


def test_a_read_only_folder_saves_nothing_and_says_so(tmp_path: Path) -> None:
    with studio_on_tmpfs(tmp_path, "1m", "ro") as (disk, client, version):
        status, answer = client.post("edit", {"version": version, "ops": [SPEED]})
        assert status == 200, answer
        status, failed = client.post("save", {"version": answer["version"]})
        assert status == 403, failed
        assert failed["error"] == (f"cannot save {MAIN}: the folder activities is read-only (read-only "
                                   "file system). Nothing was saved: the files on disk are as they were, "
                                   "your edits are kept"), failed
        assert snapshot(disk) == snapshot(CAR_MODEL)


# --- never out of step with the disk ---------------------------------------------------------------


def test_an_undo_after_a_conflict_is_unsaved_and_a_forced_save_writes_what_the_page_shows(
        car: tuple[Path, Editor]) -> None:
    root, editor = car
    main = root / MAIN
    status, answer = editor.post("edit", {"version": 0, "ops": [SPEED]})
    assert status == 200 and answer["dirty"]
    theirs = main.read_text("utf-8").replace("value: 8}", "value: 9}")

    def change_then_conflict(frames: list[dict[str, Any]]) -> bool:
        if len(frames) == 1:
            main.write_text(theirs, encoding="utf-8")
        return any(frame.get("type") == "conflict" for frame in frames[1:])

    frames = read_frames(editor.url, change_then_conflict, timeout=20)
    conflict = next(frame for frame in frames if frame.get("type") == "conflict")
    assert conflict["changed"] == [MAIN] and conflict["dirty"] is True
    status, undone = editor.post("undo", {})
    # the page shows main.yaml as loaded, the disk holds theirs: unsaved, and still a conflict
    assert status == 200 and undone["dirty"] is True, undone
    shown = editor.get("files")
    assert shown["files"][MAIN] != theirs and shown["dirty"] is True
    assert read_frames(editor.url, lambda f: len(f) >= 1)[0]["edit"]["conflict"] == [MAIN]
    status, refused = editor.post("save", {"version": undone["version"]})
    assert status == 409 and refused["conflict"] == [MAIN]
    status, saved = editor.post("save", {"version": undone["version"], "force": True})
    assert status == 200 and saved["saved"] == [MAIN] and not saved["dirty"], saved
    assert main.read_text("utf-8") == shown["files"][MAIN]


class _Session:
    """A working copy of a copy of the car and what a person (or a git checkout) does to its
    files on disk meanwhile; the model of the page is the working copy (it shows each answer)."""

    VALUES = ("55", "60", "65")

    def __init__(self, root: Path) -> None:
        self.root = root
        self.ws = Workspace(root)

    def edit(self, file: int, value: str) -> None:
        node = "set_speed" if file == 0 else "set_near"
        self.ws.edit(self.ws.version, [{"op": "set_node", "lane": "RaspberryPI", "id": node,
                                        "fields": {"value": value}}])

    def on_disk(self, file: int, value: str) -> None:
        path = self.root / (MAIN if file == 0 else "activities/measure.yaml")
        text = path.read_text("utf-8")
        path.write_text(re.sub(r"# disk: \d+\n$", "", text) + f"# disk: {value}\n", encoding="utf-8")

    def step(self, action: str, file: int, value: str) -> None:
        ws = self.ws
        try:
            if action == "edit":
                self.edit(file, value)
            elif action in ("undo", "redo"):
                getattr(ws, action)()
            elif action == "disk":
                self.on_disk(file, value)
                return  # the studio has not looked yet: the next step does
            elif action in ("save", "force"):
                ws.save(ws.version, force=action == "force")
                assert not ws.dirty  # (a change on disk not looked at yet is taken in below)
            elif action == "reload":
                ws.reload()
        except Conflict:
            pass
        ws.poll()  # the watch looks at the disk within a second

    def check(self) -> None:
        """The page shows the disk's files, or they are unsaved (and then the page says so)."""
        ws = self.ws
        disk = model_files(self.root)
        unsaved = set(ws.changed_files())
        for rel in set(disk) | set(ws.files):
            assert ws.files.get(rel) == disk.get(rel) or rel in unsaved, rel
        assert ws.dirty == bool(unsaved)
        assert set(ws.live_conflicts()) <= unsaved


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(steps=st.lists(st.tuples(st.sampled_from(["edit", "undo", "redo", "disk", "save", "force", "reload"]),
                                st.integers(0, 1), st.sampled_from(_Session.VALUES)), max_size=14))
def test_after_any_edits_undos_changes_on_disk_and_saves_the_page_is_the_disk_or_unsaved(
        tmp_path_factory: pytest.TempPathFactory, steps: list[tuple[str, int, str]]) -> None:
    root = tmp_path_factory.mktemp("session") / "car"
    shutil.copytree(CAR_MODEL, root)
    session = _Session(root)
    for action, file, value in steps:
        session.step(action, file, value)
        if action != "disk":
            session.check()
    session.ws.poll()
    session.check()
    # a forced save writes what the page shows, whatever happened before
    session.ws.save(session.ws.version, force=True)
    assert model_files(root) == session.ws.files
