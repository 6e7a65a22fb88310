"""The sim drivers and world sharing: in-process, over the world server, from another OS process."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest
from services_support import ROOM  # 2 m x 3 m room, car in the middle facing +y

from umlbot.base.errors import ConfigError, DriverError, SimError
from umlbot.base.registry import create_driver
from umlbot.services.simworld import ENV_ADDRESS, ENV_KEY, RemoteWorld, attach_local_world
from umlbot.sim import CarSpec, World, WorldServer, parse_track

AHEAD_CM = round((2.0 - CarSpec().sonar_forward_m) * 100)
PINS: dict[str, dict[str, Any]] = {"LeftActuator": {"in1": 22, "in2": 23, "watchdog_s": 2.0},
        "RightActuator": {"in1": 24, "in2": 25}}


@pytest.fixture
def world() -> Iterator[World]:
    w = World(parse_track(ROOM))
    attach_local_world(w)
    yield w
    attach_local_world(None)


def test_motor_channels_drive_their_side_with_the_real_settings(world: World) -> None:
    left = create_driver("motor", "sim", "LeftActuator", PINS["LeftActuator"])
    right = create_driver("motor", "sim", "RightActuator", PINS["RightActuator"])
    left.set_duty_cycle(60)
    left.set_direction(False)
    left.set_enabled(True)
    state = world.motor("left")
    assert (state.enabled, state.forward, state.duty_percent) == (True, False, 60)
    assert not world.motor("right").enabled
    right.set_enabled(True)
    left.stop()
    assert not world.motor("left").enabled and world.motor("left").duty_percent == 0
    right.close()
    right.close()  # twice is safe
    assert not world.motor("right").enabled
    with pytest.raises(DriverError):
        right.set_enabled(True)


def test_motor_side_from_setting_and_invert(world: World) -> None:
    channel = create_driver("motor", "sim", "Wheels", {"sim_side": "right", "invert": True})
    channel.set_direction(True)
    assert world.motor("right").forward is False
    with pytest.raises(ConfigError, match="sim_side"):
        create_driver("motor", "sim", "Wheels", {})
    with pytest.raises(ValueError):
        channel.set_duty_cycle(101)


def test_sonar_and_servo_see_the_world(world: World) -> None:
    sonar = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
    servo = create_driver("servo", "sim", "Sensor", {"gpio": 18})
    assert sonar.read_distance_cm() == AHEAD_CM
    assert sonar.max_range_cm == 400
    servo.set_angle(180)
    world.advance_to(1.0)
    assert sonar.read_distance_cm() == 100  # the left wall, 1 m away
    with pytest.raises(ValueError):
        servo.set_angle(200)
    median = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7, "samples": 3})
    assert median.read_distance_cm() == 100


def test_sonar_without_echo_reports_none() -> None:
    far = World(parse_track(ROOM.replace("2.0], [-1.0, 2.0]", "9.0], [-1.0, 9.0]")))
    attach_local_world(far)
    try:
        sonar = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
        assert sonar.read_distance_cm() is None
    finally:
        attach_local_world(None)


def test_without_a_world_the_driver_says_how_to_get_one(monkeypatch: pytest.MonkeyPatch) -> None:
    attach_local_world(None)
    monkeypatch.delenv(ENV_ADDRESS, raising=False)
    with pytest.raises(DriverError, match="umlbot sim"):
        create_driver("motor", "sim", "LeftActuator", PINS["LeftActuator"])


@pytest.fixture
def served(world: World) -> Iterator[WorldServer]:
    attach_local_world(None)  # drivers must go through the server
    server = WorldServer(world).start()
    yield server
    server.stop()


def test_remote_world_does_what_the_local_one_does(world: World, served: WorldServer) -> None:
    remote = RemoteWorld(served.address, served.key)
    remote.set_motor("left", enabled=True, forward=True, duty_percent=50)
    assert world.motor("left").enabled and world.motor("left").duty_percent == 50
    remote.set_motor("left", enabled=False)
    assert not world.motor("left").enabled
    assert remote.read_sonar_cm() == AHEAD_CM
    remote.set_servo(0)
    world.advance_to(1.0)
    assert remote.servo_angle_deg() == 0
    with pytest.raises(ValueError):
        remote.set_servo(500)
    remote.close()
    assert remote.read_sonar_cm() == 100  # reconnects after close


def test_remote_world_refuses_a_wrong_key(served: WorldServer) -> None:
    with pytest.raises(SimError, match="refused"):
        RemoteWorld(served.address, "wrong").read_sonar_cm()


def exchange(wire: Any, line: bytes) -> dict[str, Any]:
    """One line to the world server, its reply line back."""
    wire.write(line + b"\n")
    wire.flush()
    reply: dict[str, Any] = json.loads(wire.readline())
    return reply


def test_the_world_server_answers_malformed_lines(world: World, served: WorldServer) -> None:
    host, _, port = served.address.rpartition(":")
    with socket.create_connection((host, int(port)), timeout=5) as sock, sock.makefile("rwb") as wire:
        assert exchange(wire, json.dumps({"op": "hello", "key": "\u00e9" + served.key}).encode()) == {
            "ok": False, "error": "bad key"}  # a non-ASCII key is a wrong key, not a crash
    with socket.create_connection((host, int(port)), timeout=5) as sock, sock.makefile("rwb") as wire:
        assert exchange(wire, json.dumps({"op": "hello", "key": served.key}).encode())["ok"] is True
        bad = [
            b"[" * 5000,  # nested too deeply for the decoder
            b"\xff\xfe not json",
            b"[1, 2]",
            b'{"op": "set_motor", "args": [1]}',
            b'{"op": "set_motor", "args": {"side": "left", "enabled": "yes"}}',
            b'{"op": "set_motor", "args": {"side": "left", "duty_percent": NaN}}',
            b'{"op": "set_motor", "args": {"side": ' + b"[" * 100 + b"]" * 100 + b"}}",
            b'{"op": "set_servo", "args": {"degrees": ' + b"9" * 4000 + b"}}",
            b'{"op": "set_servo", "args": {}}',
            b'{"op": "fly"}',
            b'{"op": "read_sonar_cm", "pad": "' + b"x" * 200_000 + b'"}',  # over 64 KiB: ONE reply
        ]
        for line in bad:
            reply = exchange(wire, line)
            assert reply["ok"] is False and reply["error"], line[:60]
            if len(line) > 65536:
                assert reply["error"] == "unknown operation 'invalid line (longer than 64 KiB)'"
        assert not world.motor("left").enabled  # nothing of the junk reached the world
        assert exchange(wire, b'{"op": "read_sonar_cm", "args": {}}') == {"ok": True, "value": AHEAD_CM}


def test_unreachable_world_is_a_driver_error(monkeypatch: pytest.MonkeyPatch) -> None:
    attach_local_world(None)
    monkeypatch.setenv(ENV_ADDRESS, "127.0.0.1:1")
    monkeypatch.setenv(ENV_KEY, "x")
    sonar = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
    with pytest.raises(DriverError, match="unreachable"):
        sonar.read_distance_cm()


def test_a_driver_in_another_process_moves_the_shared_world(world: World, served: WorldServer) -> None:
    code = (
        "from umlbot.base.registry import create_driver\n"
        "m = create_driver('motor', 'sim', 'RightActuator', {'in1': 24, 'in2': 25})\n"
        "m.set_duty_cycle(80); m.set_enabled(True)\n"
        "s = create_driver('sonar', 'sim', 'DistanceRead', {'trigger': 8, 'echo': 7})\n"
        "print(s.read_distance_cm())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, **served.env},
                         capture_output=True, text=True, timeout=60, check=True)
    assert float(out.stdout.strip()) == AHEAD_CM
    assert world.motor("right").enabled and world.motor("right").duty_percent == 80


def test_the_motor_watchdog_counts_sim_seconds(world: World) -> None:
    # at --speed 10 a model's 3 s sleep with the motors on is 0.3 s of wall time: the watchdog
    # (watchdog_s: 2.0) must stop the motor all the same, and must not at --speed 0.1 after 0.2 s
    from umlbot.base.catalog import resolve_implementation
    from umlbot.services.motor.service import MotorService
    from umlbot.sim.clock import SimClock

    clock = SimClock(1.0)
    world.clock = clock
    impl = resolve_implementation("l298n")
    assert impl is not None
    channel = create_driver("motor", "sim", "LeftActuator", PINS["LeftActuator"])
    service = MotorService("LeftActuator", impl, channel, PINS["LeftActuator"])
    service.dutycycle(60)
    service.enabled(True)
    clock.charge(1.9)  # sim time moves on without the wall clock (no orchestrator ticks here)
    service.tick(1e9)  # the host's wall-clock reading is not what counts
    assert world.motor("left").enabled and service.stop_reason is None
    clock.charge(0.2)
    service.tick(0.0)
    assert not world.motor("left").enabled and service.stop_reason == "watchdog"
