"""`umlbot run --record`: the recorder as a process of its own beside the orchestrator.

In the orchestrator's process the recorder's decoding and writing would take turns with the lanes
for the interpreter (bench/record.py measured it); as `umlbot record --until-stopped` in its own
process, at a lower CPU priority, it costs the robot little more than the broker's copy of each
message. The recorder is subscribed
before the orchestrator starts, and ends by itself once it has written the orchestrator's final
status (the trace's last events go out before it).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

from umlbot.base.errors import UmlbotError
from umlbot.base.logs import get_logger

log = get_logger(__name__)

#: wall seconds the recorder may take to connect and subscribe
READY_TIMEOUT_S = 20.0
#: wall seconds it may take, after the run, to write the end and close the file
FINISH_TIMEOUT_S = 15.0


#: how much lower the recorder's CPU priority is than the robot's (nice(2)): on a busy machine the
#: orchestrator and the services run first, the recorder catches up when they wait (its queue
#: holds 100 000 items meanwhile)
NICENESS = 10


def _lower_priority() -> None:  # in the child, before exec
    os.nice(NICENESS)


class RecorderProcess:
    """`umlbot record --until-stopped` for one run; `start()` returns once it is subscribed."""

    def __init__(self, broker_url: str, robot: str, path: Path, ca_file: Path | None = None,
                 model: str | None = None) -> None:
        argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "record", "--robot", robot,
                "-o", str(path), "--until-stopped", "--connect-timeout", "10"]
        if ca_file is not None:
            argv += ["--ca-file", str(ca_file)]
        if model:
            argv += ["--model", model]
        self.argv = argv
        # the URL (it may hold a password) goes in the environment, not on a command line `ps` shows
        self.env = {**os.environ, "UMLBOT_BROKER": broker_url}
        self._proc: subprocess.Popen[str] | None = None
        self._ready = threading.Event()
        self._reader: threading.Thread | None = None

    def start(self) -> None:
        self._proc = subprocess.Popen(self.argv, env=self.env, stdin=subprocess.DEVNULL,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                      preexec_fn=_lower_priority)
        self._reader = threading.Thread(target=self._relay, name="umlbot-record-relay", daemon=True)
        self._reader.start()
        if not self._ready.wait(READY_TIMEOUT_S) or self._proc.poll() is not None:
            self.stop()
            raise UmlbotError("the recorder did not start (see its message above)")

    def _relay(self) -> None:
        """Its stderr goes on to ours; its first `recording …` line says it is subscribed."""
        assert self._proc is not None and self._proc.stderr is not None
        for line in self._proc.stderr:
            if line.startswith("recording "):
                self._ready.set()
                continue
            sys.stderr.write(line)
        self._ready.set()  # it ended

    def stop(self) -> int | None:
        """Wait for it to end by itself (the run has ended); interrupt it when it does not."""
        proc = self._proc
        if proc is None:
            return None
        try:
            return proc.wait(FINISH_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            try:
                return proc.wait(FINISH_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                log.warning("recorder killed: it did not end", pid=proc.pid)
                proc.kill()
                return proc.wait(5)
        finally:
            if self._reader is not None:
                self._reader.join(5)
