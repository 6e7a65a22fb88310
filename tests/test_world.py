"""The simulated world without MQTT: kinematics, ray casting, collisions, servo, track files."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from services_support import ROOM  # 2 m x 3 m room, car in the middle facing +y

from umlbot.base.errors import SimError
from umlbot.sim import CarSpec, World
from umlbot.sim.clock import SimClock
from umlbot.sim.geometry import Point, Pose, Segment, cast, rectangle_corners, rectangle_hits
from umlbot.sim.track import load_track, parse_track, tracks_dir

# no lag: speeds follow the command at once, so the expected motion is exact
IDEAL = CarSpec(motor_time_constant_s=0.0)


def world(text: str = ROOM, **kwargs: object) -> World:
    return World(parse_track(text), IDEAL, **kwargs)  # type: ignore[arg-type]


def drive(w: World, left: float, right: float, seconds: float) -> None:
    for side, duty in (("left", left), ("right", right)):
        w.set_motor(side, enabled=duty != 0, forward=duty >= 0, duty_percent=abs(duty))  # type: ignore[arg-type]
    w.advance_to(w.snapshot().time_s + seconds)


def test_straight_line_at_full_duty_covers_top_speed_times_time() -> None:
    w = world()
    drive(w, 100, 100, 1.0)
    snap = w.snapshot()
    assert snap.pose.x == pytest.approx(0.0, abs=1e-9)
    assert snap.pose.y == pytest.approx(IDEAL.top_speed_mps * 1.0, rel=1e-6)
    assert snap.distance_m == pytest.approx(0.5, rel=1e-6)
    assert snap.collisions == 0


def test_reverse_drives_backwards_and_half_duty_half_speed() -> None:
    w = world()
    drive(w, -50, -50, 1.0)
    assert w.snapshot().pose.y == pytest.approx(-0.25, rel=1e-6)


def test_duty_below_dead_band_does_not_move() -> None:
    w = world()
    drive(w, IDEAL.dead_band_percent - 1, IDEAL.dead_band_percent - 1, 1.0)
    assert w.snapshot().distance_m == 0.0


def test_disabled_channel_does_not_move() -> None:
    w = world()
    w.set_motor("left", enabled=False, duty_percent=100)
    w.set_motor("right", enabled=False, duty_percent=100)
    w.advance_to(1.0)
    assert w.snapshot().distance_m == 0.0


def test_spin_in_place_turns_at_the_documented_rate_without_moving() -> None:
    w = world()
    drive(w, -50, 50, 0.5)  # left back, right forward: counter-clockwise
    snap = w.snapshot()
    omega = 2 * 0.25 / IDEAL.turn_track_m
    assert snap.pose.heading == pytest.approx(math.pi / 2 + omega * 0.5, rel=1e-6)
    assert math.hypot(snap.pose.x, snap.pose.y) < 1e-9
    drive(w, 50, -50, 0.5)
    assert w.snapshot().pose.heading == pytest.approx(math.pi / 2, abs=1e-9)


def test_motor_lag_reaches_the_commanded_speed() -> None:
    w = World(parse_track(ROOM), CarSpec(motor_time_constant_s=0.05))
    drive(w, 100, 100, 0.5)
    assert w.snapshot().left_speed_mps == pytest.approx(0.5, rel=1e-3)
    assert w.snapshot().pose.y < 0.25  # it had to speed up first


def test_ray_hits_a_known_wall_at_the_known_distance() -> None:
    wall = [Segment(Point(-3, 2), Point(3, 2))]
    assert cast(Point(0, 0), math.pi / 2, wall) == pytest.approx(2.0)
    assert cast(Point(0, 0), -math.pi / 2, wall) is None  # behind
    assert cast(Point(0, 0), 0.0, wall) is None  # parallel
    assert cast(Point(0, 0), math.radians(45), wall) == pytest.approx(2 * math.sqrt(2))
    assert cast(Point(0, 0), math.radians(20), wall) is None  # passes the wall's end


def test_sonar_reads_the_wall_ahead_in_whole_centimetres() -> None:
    w = world()
    # sonar sits sonar_forward_m ahead of the centre; the wall ahead is at y = 2.0
    expected = round((2.0 - IDEAL.sonar_forward_m) * 100)
    assert w.read_sonar_cm() == expected
    ping = w.pings[-1]
    assert ping.distance_cm == expected and ping.origin.y == pytest.approx(IDEAL.sonar_forward_m)


def test_sonar_beam_sees_a_post_off_the_axis_within_half_the_beam() -> None:
    text = """
name: post
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: 3, x_max: 4, y_min: 3, y_max: 4}
walls:
  - [[0.10, 1.0], [0.16, 1.0]]
"""
    w = world(text)
    # the post is ~5-9° off the axis: inside the 15° beam (±7.5°), the centre ray misses it
    assert w.read_sonar_cm() == pytest.approx(89, abs=1)
    w2 = World(parse_track(text), CarSpec(motor_time_constant_s=0.0, sonar_rays=1))
    assert w2.read_sonar_cm() is None


def test_a_ping_records_where_its_echo_came_from_on_the_wall() -> None:
    # the post off the axis: the echo is on the post, not on the beam's centre line beyond it
    w = world("""
name: post
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: 3, x_max: 4, y_min: 3, y_max: 4}
walls:
  - [[0.10, 1.0], [0.16, 1.0]]
""")
    cm = w.read_sonar_cm()
    ping = w.pings[-1]
    assert cm is not None and ping.distance_cm == cm and ping.hit is not None
    assert ping.hit.y == pytest.approx(1.0) and 0.10 <= ping.hit.x <= 0.16
    range_cm = math.hypot(ping.hit.x - ping.origin.x, ping.hit.y - ping.origin.y) * 100
    assert range_cm == pytest.approx(cm, abs=0.5)
    # along the centre line, the reading would put the echo at x = 0, where there is no wall
    assert ping.origin.x + cm / 100 * math.cos(ping.angle) == pytest.approx(0.0, abs=1e-9)
    # no echo, no point
    far = world(ROOM.replace("2.0], [-1.0, 2.0]", "9.0], [-1.0, 9.0]"))
    assert far.read_sonar_cm() is None and far.pings[-1].hit is None


def test_the_plot_draws_echoes_with_and_without_their_point(tmp_path: Path) -> None:
    from umlbot.sim.plot import plot_run
    from umlbot.sim.world import Ping

    w = world()
    w.read_sonar_cm()
    placed = w.pings[-1]
    assert placed.hit is not None
    # a ping recorded without its point (as in an older trace) is drawn too, along the beam
    w._trace.pings.append(Ping(placed.time_s, placed.origin, placed.angle, placed.distance_cm))
    out = plot_run(w, tmp_path / "run.png")
    assert out.read_bytes().startswith(b"\x89PNG")


def test_sonar_without_echo_beyond_range_is_none_and_near_clamps_to_minimum() -> None:
    far = """
name: far
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: 3, x_max: 4, y_min: 3, y_max: 4}
walls:
  - [[-1.0, 4.2], [1.0, 4.2]]
"""
    assert world(far).read_sonar_cm() is None
    near = """
name: near
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: 3, x_max: 4, y_min: 3, y_max: 4}
walls:
  - [[-1.0, 0.125], [1.0, 0.135]]
"""
    # wall 1.5-2.5 cm ahead of the sonar but not touching the car's nose (0.13 m)?
    # the nose is at 0.13, so keep the wall just beyond it on the right half only
    w = world(near.replace("[[-1.0, 0.125], [1.0, 0.135]]", "[[0.0, 0.131], [1.0, 0.131]]"))
    assert w.read_sonar_cm() == IDEAL.sonar_min_cm


def test_seeded_noise_is_reproducible() -> None:
    a = [world(sonar_noise_cm=3.0, seed=7).read_sonar_cm() for _ in range(3)]
    b = [world(sonar_noise_cm=3.0, seed=7).read_sonar_cm() for _ in range(3)]
    assert a == b
    readings = {w.read_sonar_cm() for w in [world(sonar_noise_cm=3.0, seed=1)] for _ in range(20)}
    assert len(readings) > 1


def _slanted(incidence_deg: float) -> str:
    """A long wall 1 m ahead of the car, turned so that the sonar's axis meets it at `incidence_deg`."""
    a = math.radians(incidence_deg)
    x, y = 2 * math.cos(a), 2 * math.sin(a)
    return f"""
name: slanted
start: {{x: 0.0, y: 0.0, heading_deg: 90}}
goal: {{x_min: 3, x_max: 4, y_min: 3, y_max: 4}}
walls:
  - [[{-x}, {1 - y}], [{x}, {1 + y}]]
"""


def test_sonar_loses_the_echo_of_a_wall_hit_too_obliquely() -> None:
    assert IDEAL.sonar_max_incidence_deg == 50.0
    # one ray: the echo comes back up to the steepest incidence, not beyond
    one_ray = CarSpec(motor_time_constant_s=0.0, sonar_rays=1)
    seen = World(parse_track(_slanted(48.0)), one_ray).read_sonar_cm()
    assert seen == round((1.0 - IDEAL.sonar_forward_m) * 100)  # the wall crosses the axis at y = 1
    assert World(parse_track(_slanted(52.0)), one_ray).read_sonar_cm() is None
    # the 15° beam: a ray 7.5° off the axis still meets the wall at 52.5° - 7.5° = 45°
    assert world(_slanted(52.5)).read_sonar_cm() is not None
    assert world(_slanted(60.0)).read_sonar_cm() is None


def test_dropped_echoes_are_seeded_and_counted_as_no_echo() -> None:
    assert [world(sonar_drop=1.0).read_sonar_cm() for _ in range(3)] == [None, None, None]
    runs = [[w.read_sonar_cm() for _ in range(40)] for w in (world(sonar_drop=0.3, seed=5),
                                                               world(sonar_drop=0.3, seed=5))]
    assert runs[0] == runs[1]
    assert 0 < runs[0].count(None) < 40
    assert set(runs[0]) - {None} == {world().read_sonar_cm()}
    with pytest.raises(ValueError, match="dropped echoes"):
        world(sonar_drop=1.5)


def test_pings_are_60_ms_apart_and_each_costs_its_echo_time() -> None:
    clock = SimClock()  # no event loop: a charge moves sim time on at once
    w = World(parse_track(ROOM), IDEAL, clock=clock)
    for side in ("left", "right"):
        w.set_motor(side, enabled=True, forward=True, duty_percent=50)
    readings = [w.read_sonar_cm() for _ in range(3)]
    times = [ping.time_s for ping in w.pings]
    assert IDEAL.sonar_interval_s == 0.06
    # back to back, a ping waits for 60 ms after the one before; its echo takes less than that
    assert times == pytest.approx([0.0, 0.06, 0.12])
    last = readings[-1]
    assert last is not None
    assert clock.now() == pytest.approx(0.12 + 2 * last / 100 / 343.0, abs=1e-4)
    # the ping goes out after the wait, from where the car has driven meanwhile (0.25 m/s)
    assert [ping.origin.y for ping in w.pings] == pytest.approx(
        [IDEAL.sonar_forward_m + 0.25 * t for t in times])
    assert readings[0] is not None and readings[0] - last == pytest.approx(3, abs=1)  # 3 cm nearer
    # a ping asked for more than 60 ms after the last one goes out at once
    clock.charge(0.2)
    asked = clock.now()
    w.read_sonar_cm()
    assert w.pings[-1].time_s == pytest.approx(asked)
    # no echo: the sensor gives up after 38 ms, and the next ping still waits for the 60 ms
    far = World(parse_track(ROOM.replace("2.0], [-1.0, 2.0]", "9.0], [-1.0, 9.0]")), IDEAL,
                clock=SimClock())
    assert far.read_sonar_cm() is None and far.clock is not None
    assert far.clock.now() == pytest.approx(IDEAL.sonar_timeout_s)
    far.read_sonar_cm()
    assert [ping.time_s for ping in far.pings] == pytest.approx([0.0, 0.06])


def test_servo_turns_the_beam_at_a_finite_speed() -> None:
    w = world()
    w.set_servo(180)  # look left: the wall at x = -1.0
    w.advance_to(0.05)  # 30° in 50 ms at 0.1 s / 60°
    assert w.servo_angle_deg() == pytest.approx(120.0)
    w.advance_to(0.5)
    assert w.servo_angle_deg() == pytest.approx(180.0)
    assert w.read_sonar_cm() == 100
    with pytest.raises(ValueError):
        w.set_servo(181)


def test_collision_stops_the_car_at_the_wall_and_counts_once() -> None:
    w = world()
    drive(w, 100, 100, 10.0)
    snap = w.snapshot()
    assert snap.collisions == 1
    assert snap.in_contact
    nose = snap.pose.y + IDEAL.length_m / 2
    assert 2.0 - 0.005 < nose < 2.0  # stopped at the wall, within one step
    drive(w, 100, 100, 1.0)  # still pushing: the same contact, not a new collision
    assert w.snapshot().collisions == 1
    drive(w, 50, -50, 0.2)  # scraping while turning away: still the same contact
    assert w.snapshot().collisions == 1
    drive(w, -50, 50, 0.2)
    drive(w, -50, -50, 0.5)
    drive(w, 100, 100, 2.0)  # hits it again
    assert w.snapshot().collisions == 2


def test_spinning_too_close_to_a_wall_collides() -> None:
    w = world()
    drive(w, 100, 100, 10.0)  # against the wall
    drive(w, -20, -20, 0.12)  # free again, 1.2 cm off
    assert not w.snapshot().in_contact
    drive(w, -40, 40, 0.5)  # a corner swings into it
    assert w.snapshot().collisions == 2


def test_goal_reached_when_the_centre_enters_the_goal() -> None:
    w = world()
    drive(w, 100, 100, 2.9)
    assert not w.snapshot().goal_reached
    drive(w, 100, 100, 0.2)
    assert w.snapshot().goal_reached


def test_rectangle_overlap_detects_crossing_and_inside_walls() -> None:
    corners = rectangle_corners(__import__("umlbot.sim.geometry").sim.geometry.Pose(0, 0, 0), 0.26, 0.15)
    assert rectangle_hits(corners, [Segment(Point(0, -1), Point(0, 1))])
    assert rectangle_hits(corners, [Segment(Point(-0.01, 0), Point(0.01, 0))])  # wholly inside
    assert not rectangle_hits(corners, [Segment(Point(0.2, -1), Point(0.2, 1))])


def test_start_inside_a_wall_is_refused() -> None:
    with pytest.raises(ValueError, match="overlaps a wall"):
        world(ROOM.replace("x: 0.0, y: 0.0", "x: 0.95, y: 0.0"))


def test_bad_track_files_raise_sim_error_naming_the_field(tmp_path: Path) -> None:
    with pytest.raises(SimError, match="goal"):
        parse_track("name: x\nstart: {x: 0, y: 0}\nwalls: [[[0, 0], [1, 0]]]\n", "t.yaml")
    with pytest.raises(SimError, match=r"t.yaml:4:\d+: invalid track: walls.0: .*needs at least 2 points"):
        parse_track("name: x\nstart: {x: 0, y: 0}\ngoal: {x_min: 0, x_max: 1, y_min: 0, y_max: 1}\n"
                    "walls: [[[0, 0]]]\n", "t.yaml")
    with pytest.raises(SimError, match="cannot read"):
        load_track(tmp_path / "missing.yaml")


def test_every_bundled_track_loads_and_its_start_is_free() -> None:
    files = sorted(tracks_dir().glob("*.yaml"))
    names = {f.stem for f in files}
    assert {"corridor", "left_bend", "right_bend", "s_bend", "zigzag", "dead_end"} <= names
    assert len(files) >= 14
    for f in files:
        track = load_track(f)
        assert track.name == f.stem
        w = World(track)
        assert not w.snapshot().goal_reached


def _random_walls(seed: int, count: int) -> list[Segment]:
    """Polylines on a 0.1 m raster (shared corners, axis-parallel pieces: the ties of real tracks)."""
    import random

    rng = random.Random(seed)
    walls: list[Segment] = []
    while len(walls) < count:
        points = [Point(round(rng.uniform(-5, 5), 1), round(rng.uniform(-5, 5), 1))]
        for _ in range(3):
            last = points[-1]
            points.append(Point(round(last.x + rng.uniform(-1, 1), 1), round(last.y + rng.uniform(-1, 1), 1)))
        walls.extend(Segment(a, b) for a, b in itertools.pairwise(points))
    return walls


@pytest.mark.parametrize("long_wall", [False, True], ids=["compact", "with-a-200-m-wall"])
def test_the_wall_grid_answers_exactly_what_the_plain_scans_answer(long_wall: bool) -> None:
    import random

    from umlbot.sim.geometry import WallIndex, cast_hit

    walls = _random_walls(7, 900)
    if long_wall:  # spans too many cells: tested by every query
        walls.append(Segment(Point(-100, -100), Point(100, 100)))
    index = WallIndex(walls)
    assert index.gridded
    rng = random.Random(11)
    hits = 0
    for _ in range(4000):
        # origins inside and outside the grid, some rays along the axes
        origin = Point(rng.uniform(-9, 9), rng.uniform(-9, 9))
        angle = rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2, rng.uniform(-math.pi, math.pi)])
        expected = cast_hit(origin, angle, walls)
        assert index.cast_hit(origin, angle) == expected, (origin, angle)
        hits += expected is not None
        corners = rectangle_corners(Pose(origin.x, origin.y, angle), 0.26, 0.15)
        assert index.rectangle_hits(corners) == rectangle_hits(corners, walls), (origin, angle)
    assert hits > 1000  # the rays really met walls


def test_small_tracks_are_scanned_as_before() -> None:
    from umlbot.sim.geometry import WallIndex

    for path in sorted(tracks_dir().glob("*.yaml")):
        assert not WallIndex(load_track(path).segments).gridded, path.name


def test_halt_stops_the_motors_and_the_time_at_once() -> None:
    w = world()
    drive(w, 60, 60, 0.5)
    moving = w.snapshot()
    assert moving.distance_m > 0.1
    w.halt()
    assert w.halted
    assert not w.motor("left").enabled and not w.motor("right").enabled
    w.advance_to(moving.time_s + 10.0)  # a world that fell behind does not catch up any more
    w.set_motor("left", enabled=True, duty_percent=80)  # a late driver command moves nothing
    after = w.snapshot()
    assert after.time_s == moving.time_s and after.pose == moving.pose


def test_the_deadman_stops_a_side_whose_driver_stops_renewing_it() -> None:
    w = world()
    drive(w, 60, 60, 0.0)
    assert w.renew_motor("left", 1.0) is True  # the left driver arms its deadman; the right none
    w.advance_to(0.9)
    assert w.motor("left").enabled
    w.set_motor("left", duty_percent=60)  # a command renews too
    w.advance_to(1.85)
    assert w.motor("left").enabled and w.deadman_stops == []
    w.advance_to(3.0)
    assert not w.motor("left").enabled and w.motor("left").duty_percent == 0, "stopped, pins low"
    assert w.motor("right").enabled, "a side without a renewing driver has no deadman"
    ((when, side),) = w.deadman_stops
    assert side == "left" and when == pytest.approx(1.9), "at the lease's end, not the next step's"
    assert w.renew_motor("left", 1.0) is False, "its driver learns that it fired"
    assert w.renew_motor("left", 1.0) is True
    with pytest.raises(ValueError):
        w.renew_motor("left", float("nan"))


def test_a_sim_clock_waits_for_a_lease_renewal_before_time_passes_it() -> None:
    import asyncio
    import threading
    import time

    w = world()
    clock = SimClock(1000.0)  # 5 s of sleep would take 5 ms of wall time without the lease
    w.clock = clock
    drive(w, 60, 60, 0.0)
    w.renew_motor("left", 1.0)
    stop = threading.Event()

    def driver() -> None:  # a live driver renews every 0.1 s of wall time
        while not stop.wait(0.1):
            w.renew_motor("left", 1.0)

    async def model() -> float:
        started = time.monotonic()
        await clock.asleep(5.0)
        return time.monotonic() - started

    thread = threading.Thread(target=driver)
    thread.start()
    try:
        wall = asyncio.run(model())
    finally:
        stop.set()
        thread.join()
    w.advance_to(clock.now())
    assert w.motor("left").enabled and w.deadman_stops == [], "renewed in time at any speed"
    assert wall >= 0.3, "sim time waited for the renewals (1 s of lease per renewal)"
    # nobody renews any more: time waits DEADMAN_GRACE_WALL_S, then the lease ends on time
    from umlbot.sim.world import DEADMAN_GRACE_WALL_S

    last = w.snapshot().time_s

    async def later() -> float:
        started = time.monotonic()
        await clock.asleep(3.0)
        return time.monotonic() - started

    wall = asyncio.run(later())
    w.advance_to(clock.now())
    assert wall >= DEADMAN_GRACE_WALL_S * 0.9
    ((when, side),) = w.deadman_stops
    assert side == "left" and when <= last + 1.0 + 1e-6


def test_a_long_run_keeps_only_the_newest_pings_and_a_poller_sees_each_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import umlbot.sim.world as world_module

    monkeypatch.setattr(world_module, "MAX_PINGS", 50)
    w = World(parse_track(ROOM), IDEAL, clock=SimClock())
    seen, polled = 0, []
    for burst in (7, 30, 120, 3):  # the last-but-one overruns what the world keeps
        for _ in range(burst):
            w.read_sonar_cm()
        seen, new = w.pings_since(seen)
        polled.append(new)
    assert seen == 7 + 30 + 120 + 3
    assert len(w.pings) == 50, "the world keeps at most MAX_PINGS"
    assert [len(new) for new in polled] == [7, 30, 50, 3], "an overrun poller gets what is kept"
    times = [p.time_s for new in polled for p in new]
    assert times == sorted(times) and len(set(times)) == len(times), "in order, none twice"
    assert polled[-1] == w.pings[-3:]
    assert w.pings_since(seen) == (seen, [])
