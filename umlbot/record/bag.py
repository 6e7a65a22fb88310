"""One rosbag2 MCAP file, written by rosbags' rosbag2 writer and its MCAP storage.

rosbags writes a rosbag2 *directory* (`NAME/NAME.mcap` + `metadata.yaml`); a recording is handed
around as one file, so `McapBag` gives that writer a storage that writes to the file it is told
(profile `ros2`, schemas `ros2msg`, messages `cdr`, the `rosbag2` metadata record with the bag's
metadata at the end: what `ros2 bag record -s mcap` writes) and drops the `metadata.yaml`.

Two promises beyond rosbags': the open chunk is closed and flushed every `flush_every_s` (a killed
run loses at most that much), and a write that fails (disk full, file too large) ends the bag
*cleanly*: the file is cut back to the last whole chunk and closed with an MCAP footer without a
summary, which every MCAP reader reads to its end (`failed` says why; later writes are dropped).
"""

from __future__ import annotations

import contextlib
import errno
import os
import struct
import tempfile
import time
import uuid
from collections.abc import Callable
from importlib.metadata import version
from io import BytesIO
from pathlib import Path
from typing import Any

from umlbot.base import rosmsg
from umlbot.base.errors import ConfigError
from umlbot.base.files import os_problem
from umlbot.base.logs import get_logger

log = get_logger(__name__)

#: close the open chunk after this many wall seconds (and flush it to disk).
FLUSH_EVERY_S = 1.0
#: the rosbag2 metadata version written (ROS 2 Jazzy's).
ROSBAG2_VERSION = 9
MAGIC = b"\x89MCAP0\r\n"
#: a chunk this big (bytes, uncompressed) is closed and written (rosbags' size)
CHUNK_BYTES = 2**20
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")


def check_writable(path: Path) -> None:
    """Raise ConfigError now when `path` cannot be written (before a run starts, not in it)."""
    existed = path.exists()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT, 0o644))
    except OSError as exc:
        raise ConfigError(f"cannot write the recording {path}: {_why(exc)}") from None
    if not existed:
        path.unlink()


def _classes() -> tuple[type[Any], type[Any]]:
    """rosbags' Writer and MCAP storage, adapted to one file (imported on first use)."""
    writer_mod = rosmsg.require("rosbags.rosbag2.writer", "record", "MCAP recordings")
    storage_mod = rosmsg.require("rosbags.rosbag2.storage_mcap", "record", "MCAP recordings")
    from rosbags.rosbag2.enums import StoragePlugin

    class FileStorage(storage_mod.McapWriter):  # type: ignore[misc,name-defined]
        """rosbags' MCAP storage writing to `file` (it would open `path/path.name.mcap`)."""

        def __init__(self, file: WholeFile, path: Path) -> None:
            # the state rosbags' McapWriter.__init__ sets up, without its file and compression
            from collections import defaultdict

            self.path = path
            self.bio = file
            file.write(MAGIC)
            rec = BytesIO()
            storage_mod.write_string(rec, "ros2")
            storage_mod.write_string(rec, f"rosbags-{version('rosbags')} umlbot")
            storage_mod.write_record(file, 0x01, rec)
            self.schemas: list[Any] = []
            self.channels: list[Any] = []
            self.chunks: list[BytesIO] = []
            self.chunk = storage_mod.PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
            self.compression = ""
            self.compressor = lambda data: data
            self.message_start_time = 2**63 - 1
            self.message_end_time = 0
            self.channel_stats: dict[int, int] = {}

    class FileWriter(writer_mod.Writer):  # type: ignore[misc,name-defined]
        """rosbags' rosbag2 Writer with `FileStorage`; its metadata.yaml goes to a temporary folder."""

        def __init__(self, file: WholeFile, path: Path, scratch: Path) -> None:
            super().__init__(scratch / f"bag-{uuid.uuid4().hex}", version=ROSBAG2_VERSION,
                             storage_plugin=StoragePlugin.MCAP)
            self.metapath = scratch / "metadata.yaml"
            self._file, self._target = file, path

        def open(self) -> None:
            self.storage = FileStorage(self._file, self._target)

    return FileStorage, FileWriter


class McapBag:
    """A rosbag2 MCAP file being written: `channel(topic, msgtype)`, `write(...)`, `close()`.

    Not thread-safe: one writer thread owns it (`umlbot.record.Recorder`).
    """

    def __init__(self, path: str | Path, file: WholeFile | None = None,
                 custom_data: dict[str, str] | None = None, flush_every_s: float = FLUSH_EVERY_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.path = Path(path)
        self.store = rosmsg.typestore("record")
        _, writer_class = _classes()
        if file is None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                file = WholeFile(self.path)
            except OSError as exc:
                raise ConfigError(f"cannot write the recording {self.path}: {_why(exc)}") from None
        self._file = file
        self._scratch = tempfile.TemporaryDirectory(prefix="umlbot-bag-")
        self._writer = writer_class(file, self.path, Path(self._scratch.name))
        for key, value in (custom_data or {}).items():
            self._writer.set_custom_data(key, value)
        self._connections: dict[tuple[str, str], Any] = {}
        self._flush_every_s = flush_every_s
        self._clock = clock
        self._chunk_opened: float | None = None
        #: file offset up to which everything is on disk and whole (header, then whole chunks)
        self._good = 0
        self.closed = False
        #: why writing stopped early (the OS error), or None
        self.failed: str | None = None
        #: messages written (and whole on disk once the bag is closed)
        self.written = 0
        try:
            self._writer.open()
            self._flush()
        except OSError as exc:
            self._fail(exc)

    def channel(self, topic: str, msgtype: str) -> Any:
        """The connection of `topic` (made on first use) for messages of `msgtype`."""
        key = (topic, msgtype)
        connection = self._connections.get(key)
        if connection is None:
            connection = self._writer.add_connection(topic, msgtype, typestore=self.store)
            self._connections[key] = connection
        return connection

    def write(self, topic: str, msgtype: str, message: Any, stamp_ns: int) -> None:
        """Serialise `message` (a typestore message of `msgtype`) to CDR and add it at `stamp_ns`."""
        self.write_cdr(topic, msgtype, self.store.serialize_cdr(message, msgtype), stamp_ns)

    def write_cdr(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None:
        if self.closed or self.failed is not None:
            return
        connection = self.channel(topic, msgtype)
        # rosbags' Writer.write, without its search of every connection for this one (it is ours),
        # and its storage's write in one `struct` pass (the same bytes: tests/test_record_mcap.py)
        writer, stamp = self._writer, max(0, stamp_ns)
        storage = writer.storage
        cid = connection.id
        if stamp < storage.message_start_time:
            storage.message_start_time = stamp
        if stamp > storage.message_end_time:
            storage.message_end_time = stamp
        storage.channel_stats[cid] += 1
        chunk = storage.chunk
        if stamp < chunk.message_start_time:
            chunk.message_start_time = stamp
        if stamp > chunk.message_end_time:
            chunk.message_end_time = stamp
        bio = chunk.bio
        chunk.msgs[cid].append((stamp, bio.tell()))
        # a Message record: opcode, length; channel id, sequence (rosbags writes 0), log and
        # publish time (both the stamp), the data
        bio.write(_MESSAGE_HEAD.pack(0x05, 22 + len(data), cid, 0, stamp, stamp))
        bio.write(data)
        try:
            if bio.tell() > CHUNK_BYTES:  # as rosbags: a full chunk goes to the file
                storage.close_chunk()
        except OSError as exc:
            self._fail(exc)
            return
        writer.counts[connection.id] += 1
        if stamp < writer.min_timestamp:
            writer.min_timestamp = stamp
        if stamp > writer.max_timestamp:
            writer.max_timestamp = stamp
        self.written += 1
        if self._chunk_opened is None:
            self._chunk_opened = self._clock()
        if self._writer.storage.chunk.bio.tell() == 0:  # rosbags closed a full chunk itself
            self._chunk_opened = None
            self._flush()

    def tick(self) -> None:
        """Close and flush the open chunk when it is older than `flush_every_s` (call it often)."""
        opened = self._chunk_opened
        if opened is not None and self._clock() - opened >= self._flush_every_s and self.failed is None:
            storage = self._writer.storage
            try:
                if storage.chunk.bio.tell():
                    storage.close_chunk()
            except OSError as exc:
                self._fail(exc)
                return
            self._chunk_opened = None
            self._flush()

    def _flush(self) -> None:
        if self.failed is not None:
            return
        try:
            self._file.flush()
            self._good = self._file.tell()
        except OSError as exc:
            self._fail(exc)

    def _fail(self, exc: OSError) -> None:
        """Writing failed: keep what is whole, end the file with a footer, write nothing more."""
        if self.failed is not None:
            return
        self.failed = f"{exc.strerror or exc} ({self.path})"
        log.warning("recording stopped: the file cannot be written", file=str(self.path), error=str(exc))
        with contextlib.suppress(Exception):
            self._writer.storage = None  # rosbags must not try to write its summary
        _end_cut_file(self._file, self._good)

    def close(self) -> None:
        """Write the summary and the rosbag2 metadata, close the file; idempotent."""
        if self.closed:
            return
        self.closed = True
        try:
            if self.failed is None:
                try:
                    self._writer.close()
                except OSError as exc:
                    self._fail(exc)
                else:
                    self._flush()
        finally:
            with contextlib.suppress(OSError):
                self._file.close()
            self._scratch.cleanup()


def _why(exc: OSError) -> str:
    if exc.errno in (errno.EEXIST, errno.ENOTDIR):  # mkdir of a folder that is a file
        return "a part of its folder is a file"
    return os_problem(exc)


class WholeFile:
    """A file written with whole writes and no buffer: `write` writes all of its bytes or raises
    (a raw write may write part and return the count, which rosbags does not look at), so the
    offset `tell()` gives is always what is on disk, and a failed write leaves nothing behind in a
    buffer that a later flush would try again."""

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0), 0o644)
        self._offset = 0

    def write(self, data: bytes | bytearray | memoryview) -> int:
        view = memoryview(data).cast("B")
        while view:
            done = os.write(self._fd, view)
            if done <= 0:  # not seen on Linux; a disk that takes nothing must not loop forever
                raise OSError(28, "No space left on device")
            self._offset += done
            view = view[done:]
        return len(data)

    def flush(self) -> None:
        """Nothing is buffered."""

    def tell(self) -> int:
        return self._offset

    def cut(self, size: int) -> None:
        """Drop everything after the first `size` bytes and write on from there."""
        os.ftruncate(self._fd, size)
        os.lseek(self._fd, size, os.SEEK_SET)
        self._offset = size

    def close(self) -> None:
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)


def _end_cut_file(file: WholeFile, good: int) -> None:
    """Cut `file` back to `good` bytes (the header and the whole chunks) and end it with a DataEnd
    record and a footer without a summary: a valid MCAP however far the failed write got."""
    end = (b"\x0f" + (4).to_bytes(8, "little") + bytes(4)  # DataEnd, no CRC
           + b"\x02" + (20).to_bytes(8, "little") + bytes(20)  # Footer: no summary, no CRC
           + MAGIC)
    try:
        file.cut(good)
        file.write(end)
    except OSError:
        # not even the footer fits: the whole chunks alone are still read by streaming readers
        with contextlib.suppress(OSError):
            file.cut(good)
