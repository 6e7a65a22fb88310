"""Recording (`--record FILE.mcap`, `umlbot record`): what it costs the robot, how big, how fast.

Three parts, on a Mosquitto started by this script (`set_tcp_nodelay true`, as deployed):

(a) `orchestrator`: the loop of `LeftActuator.dutycycle(50)` actions of bench/orchestrator.py
    against a mock motor service in its own process, in rotating blocks of four variants: the raw
    paho requester (the baseline), the model traced (`umlbot run`), the model traced and recorded
    as `umlbot run --record` does it (`recorded`: `umlbot record --until-stopped` as a process of
    its own), and recorded by a `Recorder` inside the orchestrator's process (`inprocess`: the
    trace from its listener, calls from the bus; what `--record` did first). p50/p99 of each and
    the ratios against raw (targets p50 <= 1.25x, p99 <= 1.5x).
(b) `size`: the reference car on the s_bend track in the simulator with `--record`: bytes per
    minute of sim time, and the messages per topic.
(c) `throughput`: a publisher sends `--rate` trace events per second for `--seconds` to the trace
    topic, in the orchestrator's form (a JSON array every 20 ms) with the node names of a
    2 000-node model (20 lanes of 100), while a `Recorder` subscribed from outside (as `umlbot
    record`) writes them: events sent, events in the file (read back with the `mcap` package),
    dropped. Then `writer_events_per_s`: trace events handed to a recorder as fast as a loop can,
    and the time until all are in the file (the writer thread's own rate).

(d) `cpu` (only when asked for): the recorder process's CPU seconds per message it recorded, as
    `run --record` runs it, for the loop model (see `measure_cpu`); `--old DIR` alternates with
    the `umlbot` package in DIR.

The last output line is one JSON object {"orchestrator": {…}, "size": {…}, "throughput": {…}}.

    python bench/record.py [--n 2000] [--blocks 12] [--rate 2000] [--seconds 10]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

from orchestrator import LOOP, ROBOT, RawRequester, compile_text, motor_service, run_broker, spoken_protocol
from rpc import _raw_client, percentile

from umlbot.base.logs import configure_logging
from umlbot.record import RecorderProcess, open_file_recorder
from umlbot.services.bus import BrokerSettings
from umlbot.services.orchestrator import Orchestrator

REPO = Path(__file__).resolve().parent.parent


def _run(url: str, model: Any, recording: Path | None, own_process: bool = True) -> list[float]:
    """One run of the loop model, traced; recorded to `recording` when given (by a process of its
    own, or in this one). Its action latencies."""
    settings = BrokerSettings.from_url(url)
    recorder = None
    if recording is not None and own_process:
        process = RecorderProcess(url, ROBOT, recording, model=model.name)
        process.start()
        try:
            latencies = _run(url, model, None)
        finally:
            code = process.stop()
        if code != 0 or not recording.exists():
            raise RuntimeError(f"the recorder failed ({code})")
        return latencies
    if recording is not None:
        recorder = open_file_recorder(recording, ROBOT, "wall", time.time)
        recorder.listen(settings, trace=False)
    orchestrator = Orchestrator(model, settings, robot=ROBOT, trace=True, handle_signals=False,
                                startup_timeout_s=15.0,
                                trace_listener=recorder.on_trace if recorder is not None else None)
    try:
        code = orchestrator.run_sync()
    finally:
        if recorder is not None:
            stats = recorder.close()
            if stats.dropped or stats.failed:
                raise RuntimeError(f"the recording lost events: {stats}")
    if code != 0:
        raise RuntimeError(f"the orchestrator failed: {orchestrator.failure}")
    return list(orchestrator.stats.action_latency_s)


def _cpu_s(pid: int) -> float:
    """utime + stime of process `pid` so far (seconds)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure_cpu(url: str, n: int, runs: int, folder: Path, old: str | None) -> dict[str, Any]:
    """The recorder process's CPU per message it recorded, as `run --record` runs it, for the loop
    model: its CPU seconds (utime + stime: load-insensitive, CPU not wall time) from when it is
    subscribed to when it has ended (`getrusage` of the children), over the messages in its file.
    Each run records n/5 actions, then n: `marginal_us` is the slope between them (the cost of one
    more message, without the start and the end of a recording). With `old` (a folder holding an
    older `umlbot` package) every run does both, the recorder of `old` first, then this one."""
    import resource

    from mcap.reader import make_reader

    sizes = (max(1, n // 5), n)
    models = {size: compile_text(LOOP.format(n=size)) for size in sizes}
    variants = ["new"] if old is None else ["old", "new"]
    cpu: dict[tuple[str, int], list[float]] = {(v, size): [] for v in variants for size in sizes}
    counts: dict[tuple[str, int], int] = {}
    pythonpath: str | None = os.environ.get("PYTHONPATH")
    with motor_service(url):
        for run in range(runs):
            for size in sizes:
                for variant in variants:
                    path = folder / f"cpu-{variant}{size}-{run}.mcap"
                    if old is not None and variant == "old":
                        os.environ["PYTHONPATH"] = old if not pythonpath else f"{old}:{pythonpath}"
                    process = RecorderProcess(url, ROBOT, path, model=models[size].name)
                    if pythonpath is None:
                        os.environ.pop("PYTHONPATH", None)
                    else:
                        os.environ["PYTHONPATH"] = pythonpath
                    process.start()
                    assert process._proc is not None
                    started = _cpu_s(process._proc.pid)
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    try:
                        _run(url, models[size], None)
                    finally:
                        code = process.stop()
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    if code != 0:
                        raise RuntimeError(f"the recorder failed ({code})")
                    used = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime) - started
                    with path.open("rb") as stream:
                        counts[(variant, size)] = sum(1 for _ in make_reader(stream).iter_messages())
                    cpu[(variant, size)].append(used)
    result: dict[str, Any] = {"n": n, "runs": runs}
    small, large = sizes
    for variant in variants:
        marginal = [(b - a) / (counts[(variant, large)] - counts[(variant, small)]) * 1e6
                    for a, b in zip(cpu[(variant, small)], cpu[(variant, large)], strict=True)]
        whole = [c / counts[(variant, large)] * 1e6 for c in cpu[(variant, large)]]
        result[f"{variant}_messages"] = counts[(variant, large)]
        result[f"{variant}_cpu_s"] = [round(c, 3) for c in cpu[(variant, large)]]
        result[f"{variant}_us_per_message"] = [round(v, 1) for v in whole]
        result[f"{variant}_marginal_us"] = [round(v, 1) for v in marginal]
        result[f"{variant}_marginal_median_us"] = round(sorted(marginal)[len(marginal) // 2], 1)
    if old is not None:
        result["factor"] = round(result["old_marginal_median_us"] / result["new_marginal_median_us"], 2)
    return result


def measure_orchestrator(url: str, n: int, blocks: int, folder: Path) -> dict[str, Any]:
    per_block = max(1, n // blocks)
    model = compile_text(LOOP.format(n=per_block))
    samples: dict[str, list[float]] = {"raw": [], "traced": [], "recorded": [], "inprocess": []}
    with motor_service(url):
        raw = RawRequester(url, spoken_protocol(url))  # the orchestrator's MQTT version
        try:
            for _ in range(100):
                raw.round_trip()
            _run(url, compile_text(LOOP.format(n=100)), folder / "warm.mcap")
            variants = list(samples)
            for block in range(blocks):
                for variant in variants[block % 4:] + variants[:block % 4]:
                    if variant == "raw":
                        samples["raw"].extend(raw.round_trip() for _ in range(per_block))
                    else:
                        recording = None if variant == "traced" else folder / f"{variant}{block}.mcap"
                        samples[variant].extend(_run(url, model, recording, variant == "recorded"))
        finally:
            raw.close()
    result: dict[str, Any] = {"n": len(samples["raw"])}
    for variant, values in samples.items():
        result[f"{variant}_p50_ms"] = round(percentile(values, 50) * 1000, 4)
        result[f"{variant}_p99_ms"] = round(percentile(values, 99) * 1000, 4)
    for variant in ("traced", "recorded", "inprocess"):
        for q in ("p50", "p99"):
            result[f"ratio_{variant}_{q}"] = round(result[f"{variant}_{q}_ms"] / result[f"raw_{q}_ms"], 3)
    result["targets_met"] = result["ratio_recorded_p50"] <= 1.25 and result["ratio_recorded_p99"] <= 1.5
    return result


def measure_size(url: str, folder: Path, speed: float) -> dict[str, Any]:
    from mcap.reader import make_reader

    from umlbot.record import SimRecording
    from umlbot.sim.runner import SimOptions, run_sim
    from umlbot.sim.track import tracks_dir

    path = folder / "car.mcap"
    recording = SimRecording(path, model="robot_car")
    options = SimOptions(model=REPO / "models" / "robot_car", track=tracks_dir() / "s_bend.yaml", speed=speed,
                         broker_url=url, timeout_s=120.0)
    try:
        result = run_sim(options, observe=recording.observe, trace_listener=recording.on_trace)
    finally:
        stats = recording.close()
    counts: Counter[str] = Counter()
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
        assert summary is not None and summary.statistics is not None
        for channel in summary.channels.values():
            counts[channel.topic] = summary.statistics.channel_message_counts.get(channel.id, 0)
    size = path.stat().st_size
    return {"track": "s_bend", "speed": speed, "sim_s": round(result.sim_s, 2),
            "wall_s": round(result.wall_s, 2), "goal": result.goal_reached, "bytes": size,
            "messages": stats.messages,
            "bytes_per_sim_minute": round(size / (result.sim_s / 60.0)),
            "messages_per_sim_minute": round(stats.messages / (result.sim_s / 60.0)),
            "top_topics": dict(counts.most_common(5))}


def measure_throughput(url: str, rate: float, seconds: float, folder: Path, total: int) -> dict[str, Any]:
    from mcap.reader import make_reader

    from umlbot.record import Recorder

    path = folder / "load.mcap"
    recorder = open_file_recorder(path, ROBOT, "wall", time.time)
    recorder.listen(BrokerSettings.from_url(url), trace=True)
    port = int(url.rsplit(":", 1)[1])
    publisher = _raw_client(port, "trace-load")
    lanes = [f"Lane{i}" for i in range(20)]
    topic = f"umlbot/{ROBOT}/orchestrator/trace"
    per_batch = max(1, round(rate * 0.02))
    batches = round(seconds / 0.02)
    sent = 0
    began = time.perf_counter()
    for batch in range(batches):
        now = time.time()
        events = []
        for _ in range(per_batch):
            sent += 1
            lane = lanes[sent % 20]
            events.append({"lane": lane, "node": f"n{sent % 100}", "kind": "action", "start": now, "end": now,
                           "duration_ms": 0.2, "level": "info", "detail": f"{lane}.step()", "seq": sent})
        publisher.publish(topic, json.dumps(events, separators=(",", ":")), qos=0)
        delay = began + (batch + 1) * 0.02 - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    elapsed = time.perf_counter() - began
    time.sleep(0.5)  # the last batches cross the broker
    stats = recorder.close()
    publisher.disconnect()
    publisher.loop_stop()
    with path.open("rb") as stream:
        trace_topic = f"/umlbot/{ROBOT}/orchestrator/trace"
        in_file = sum(1 for _ in make_reader(stream).iter_messages(topics=[trace_topic]))

    # the writer thread alone: events handed over as fast as a loop can
    fast = Recorder(ROBOT, [], max_queue=200_000)
    from umlbot.record.bag import McapBag

    bag = McapBag(folder / "fast.mcap")
    fast.sinks.append(bag)
    event = {"lane": "Lane0", "node": "n0", "kind": "action", "start": 1.0, "end": 1.0, "duration_ms": 0.2,
             "level": "info", "detail": "Lane0.step()"}
    started = time.perf_counter()
    for seq in range(1, total + 1):
        fast.on_trace({**event, "seq": seq})
    fast_stats = fast.close(timeout=300)
    writer_s = time.perf_counter() - started
    return {"rate_per_s": rate, "seconds": round(elapsed, 2), "sent": sent, "in_file": in_file,
            "dropped": stats.dropped, "lost": sent - in_file, "bytes": path.stat().st_size,
            "writer_events": total, "writer_dropped": fast_stats.dropped,
            "writer_events_per_s": round(total / writer_s)}


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--n", type=int, default=2000, help="actions per variant")
    parser.add_argument("--blocks", type=int, default=12, help="rotating measurement blocks")
    parser.add_argument("--rate", type=float, default=2000.0, help="trace events per second (throughput)")
    parser.add_argument("--seconds", type=float, default=10.0, help="seconds of trace load (throughput)")
    parser.add_argument("--writer-events", type=int, default=100_000, help="events for writer_events_per_s")
    parser.add_argument("--size-speed", type=float, default=1.0,
                        help="sim speed of the size run (1: as on the robot; the world is sampled "
                        "in wall time)")
    parser.add_argument("--parts", default="orchestrator,size,throughput",
                        help="any of orchestrator, size, throughput, cpu (not in the default)")
    parser.add_argument("--cpu-runs", type=int, default=3, help="runs of the cpu part")
    parser.add_argument("--old", default=None,
                        help="cpu part: a folder holding an older umlbot package to alternate with")
    options = parser.parse_args()
    configure_logging("WARNING")
    parts = options.parts.split(",")
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="umlbot-bench-record-") as tmp, run_broker("mosquitto") as url:
        folder = Path(tmp)
        if "orchestrator" in parts:
            out["orchestrator"] = measure_orchestrator(url, options.n, options.blocks, folder)
            print(f"orchestrator: {out['orchestrator']}", file=sys.stderr, flush=True)
        if "size" in parts:
            out["size"] = measure_size(url, folder, options.size_speed)
            print(f"size: {out['size']}", file=sys.stderr, flush=True)
        if "throughput" in parts:
            out["throughput"] = measure_throughput(url, options.rate, options.seconds, folder,
                                                   options.writer_events)
            print(f"throughput: {out['throughput']}", file=sys.stderr, flush=True)
        if "cpu" in parts:
            out["cpu"] = measure_cpu(url, options.n, options.cpu_runs, folder, options.old)
            print(f"cpu: {out['cpu']}", file=sys.stderr, flush=True)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
