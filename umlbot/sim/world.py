"""The simulated world: one car on one track, integrated in fixed steps of sim time.

The car is the reference robot: a 4WD chassis (0.26 m x 0.15 m footprint) with 65 mm wheels
driven as two sides (skid steering), an HC-SR04 on the front turned by a 180° servo. The world is
thread-safe; the sim drivers call it from service threads (or, through `umlbot.sim.sharing`, from
other processes) while `WorldLoop` advances it with the clock.

Conventions: metres, seconds of sim time, headings in radians counter-clockwise from +x. Servo
angle 90° points the sonar straight ahead, larger angles turn it to the left (counter-clockwise),
so 180° looks left and 0° looks right.
"""

from __future__ import annotations

import itertools
import math
import random
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from umlbot.base.clock import Clock
from umlbot.base.errors import SimError
from umlbot.base.logs import get_logger
from umlbot.services.simworld import Side, StereoImages
from umlbot.sim.geometry import Point, Pose, Segment, WallIndex, incidence, rectangle_corners
from umlbot.sim.track import Track

log = get_logger(__name__)


#: A car scraping along a wall touches it again and again; a new collision is counted only after
#: it has moved free of every wall for this long (sim seconds).
CONTACT_SETTLE_S = 0.1

SPEED_OF_SOUND_MPS = 343.0
#: wall seconds a simulator clock waits at most for a motor driver to renew its lease before the
#: lease expires (the driver is taken for frozen or dead, and the world stops its motor)
DEADMAN_GRACE_WALL_S = 1.0


@dataclass(frozen=True)
class CarSpec:
    """The simulated car's physical constants (defaults: the reference robot car).

    Side speed = `top_speed_mps` x duty / 100 when the channel is enabled and the duty is at least
    `dead_band_percent` (below it the geared motors stall), else 0; the side's speed follows that
    target with the time constant `motor_time_constant_s`. Turning rate = (right - left) /
    `turn_track_m`; the effective track is wider than the 0.13 m wheel track because skid-steered
    wheels slip sideways when the car turns.
    """

    length_m: float = 0.26
    width_m: float = 0.15
    wheel_diameter_m: float = 0.065
    top_speed_mps: float = 0.5  # 65 mm wheel at ~150 rpm under load at 100 % duty
    dead_band_percent: float = 20.0
    motor_time_constant_s: float = 0.03
    turn_track_m: float = 0.20
    sonar_forward_m: float = 0.11  # sonar sits this far ahead of the centre
    sonar_min_cm: int = 2
    sonar_max_cm: int = 400
    sonar_beam_deg: float = 15.0
    sonar_rays: int = 7
    sonar_max_incidence_deg: float = 50.0  # a wall hit more obliquely reflects the ping away
    sonar_interval_s: float = 0.06  # the HC-SR04 needs 60 ms between pings
    sonar_timeout_s: float = 0.038  # no echo: the sensor gives up after ~38 ms
    servo_deg_per_s: float = 600.0  # 0.1 s per 60°
    servo_max_deg: float = 180.0


@dataclass
class MotorChannelState:
    """What the L298N channel of one side is told: on/off, direction, duty."""

    enabled: bool = False
    forward: bool = True
    duty_percent: float = 0.0
    speed_mps: float = 0.0  # the side's actual speed, lagging the command


@dataclass(frozen=True)
class Ping:
    """One sonar measurement: when, from where, in which direction, and the reported range.

    `hit` is where the echo came from: the point of the wall that the nearest echoing ray of the
    beam met (it may lie off the beam's centre line, up to half the beam's width to the side).
    None when no echo was reported, or for a ping recorded without it.
    """

    time_s: float
    origin: Point
    angle: float
    distance_cm: int | None
    hit: Point | None = None


@dataclass(frozen=True)
class WorldSnapshot:
    """A consistent copy of the world's state for progress lines and summaries."""

    time_s: float
    pose: Pose
    distance_m: float
    collisions: int
    in_contact: bool
    goal_reached: bool
    servo_deg: float
    left_speed_mps: float
    right_speed_mps: float


@dataclass
class _Servo:
    target_deg: float = 90.0
    angle_deg: float = 90.0


#: what a world keeps of its run, newest first out: a sim that runs for hours (the studio's, a
#: soak) must not grow without bound. ~35 min of pings at one per 60 ms; ~28 min of path at 0.3 m/s
#: (a point every 5 mm); collisions stop the car, so a few hundred is plenty.
MAX_PINGS = 35_000
MAX_PATH_POINTS = 100_000
MAX_COLLISION_POINTS = 1_000


@dataclass
class _Trace:
    path: deque[tuple[float, float, float]] = field(  # (t, x, y)
        default_factory=lambda: deque(maxlen=MAX_PATH_POINTS)
    )
    pings: deque[Ping] = field(default_factory=lambda: deque(maxlen=MAX_PINGS))
    pings_total: int = 0  # every ping of the run, the dropped ones included
    collision_points: deque[tuple[float, float]] = field(
        default_factory=lambda: deque(maxlen=MAX_COLLISION_POINTS)
    )


class World:
    """The car on a track. Drivers call `set_motor`, `renew_motor`, `set_servo`, `read_sonar_cm`.

    With a `clock`, every call first advances the world to the clock's time, so commands take
    effect at the sim time they arrive, however late the world loop runs.

    The motors have a deadman outside their driver's process, as on the robot (a pigpiod script,
    finite lgpio PWM bursts): once a driver renews a side (`renew_motor(side, lease_s)`), the world
    stops that side by itself when `lease_s` of world time pass without a renewal or a command
    (`deadman_stops`). A simulator clock that can hold (`SimClock.hold`) does not move past a
    lease's end for up to `DEADMAN_GRACE_WALL_S` wall seconds while it waits for the renewal, so a
    live driver is never taken for dead however fast the run goes.
    """

    def __init__(
        self,
        track: Track,
        car: CarSpec | None = None,
        *,
        clock: Clock | None = None,
        sonar_noise_cm: float = 0.0,
        sonar_drop: float = 0.0,
        seed: int | None = None,
        step_s: float = 0.005,
    ) -> None:
        if not 0.0 <= sonar_drop <= 1.0:
            raise ValueError(f"the share of dropped echoes must be 0..1, got {sonar_drop}")
        self.track = track
        self.car = car or CarSpec()
        self.clock = clock
        self.step_s = step_s
        #: the world halts itself (and its clock) the moment the goal is reached ...
        self.halt_at_goal = False
        #: ... or the collision count reaches this
        self.max_collisions: int | None = None
        self.sonar_noise_cm = sonar_noise_cm
        self.sonar_drop = sonar_drop
        self._rng = random.Random(seed)
        self._walls: list[Segment] = track.segments
        self._index = WallIndex(self._walls)  # a grid on big tracks: pings and steps test near walls
        self._lock = threading.RLock()
        self._halted = threading.Event()  # set by halt(): time stands still, the motors are off
        self._time = 0.0
        self._pose = track.start.pose
        self._motors: dict[Side, MotorChannelState] = {"left": MotorChannelState(),
                                                       "right": MotorChannelState()}
        self._servo = _Servo()
        #: side -> (lease seconds, world time it ends) once its driver renews it
        self._leases: dict[Side, tuple[float, float]] = {}
        self._fired: set[Side] = set()  # sides the deadman stopped since their last renewal
        #: (world time, side) of every deadman stop
        self.deadman_stops: list[tuple[float, Side]] = []
        self._distance = 0.0
        self._collisions = 0
        self._in_contact = False
        self._last_contact_s = -math.inf
        self._last_ping_s = -math.inf
        self._goal_reached = track.goal.contains(self._pose.x, self._pose.y)
        self._trace = _Trace()
        #: the stereo camera's renderers by image size (made on first use: numpy), and a switch
        #: that makes the camera stop delivering frames (a test of the fail-safe)
        self._renderers: dict[tuple[int, int], Any] = {}
        self._camera_seed = seed
        self._last_picture: tuple[tuple[int, int], Pose, StereoImages] | None = None
        self.camera_stopped = False
        self._trace.path.append((0.0, self._pose.x, self._pose.y))
        if self.hits_wall(self._pose):
            raise ValueError(f"track {track.name!r}: the car's start footprint overlaps a wall")

    # --- commands from the drivers -------------------------------------------------------------

    def set_motor(
        self,
        side: Side,
        *,
        enabled: bool | None = None,
        forward: bool | None = None,
        duty_percent: float | None = None,
    ) -> None:
        """Change one side's channel; arguments left None keep their value. A command renews the
        side's lease (a driver that commands is alive)."""
        with self._lock:
            self._sync()
            channel = self._motors[side]
            if duty_percent is not None and not 0 <= duty_percent <= 100:
                raise ValueError(f"duty must be 0..100 %, got {duty_percent}")
            if enabled is not None:
                channel.enabled = enabled
            if forward is not None:
                channel.forward = forward
            if duty_percent is not None:
                channel.duty_percent = duty_percent
            lease = self._leases.get(side)
            if lease is not None:
                self._leases[side] = (lease[0], self._time + lease[0])
            self._hold_clock(side)

    def renew_motor(self, side: Side, lease_s: float) -> bool:
        """The driver of `side` is alive: the deadman stops the side when `lease_s` seconds of
        world time pass without another renewal or command (0: no deadman for it).

        Returns False when the deadman stopped the side since the last renewal (the driver
        learns that its motor was stopped behind its back), else True.
        """
        if not lease_s >= 0:
            raise ValueError(f"the lease must be >= 0 s, got {lease_s}")
        # the clock's time, without integrating up to it: a renewal comes at a wall-clock moment,
        # and a step split there would make the run depend on the machine's timing
        now = self.time_s()
        with self._lock:
            fired = side in self._fired
            self._fired.discard(side)
            if lease_s > 0:
                self._leases[side] = (float(lease_s), now + lease_s)
            else:
                self._leases.pop(side, None)
            self._hold_clock(side)
        return not fired

    def _hold_clock(self, side: Side) -> None:
        """Ask a clock that can hold not to pass the side's lease while the side drives (caller
        holds the lock)."""
        hold, unhold = getattr(self.clock, "hold", None), getattr(self.clock, "unhold", None)
        if hold is None or unhold is None:
            return
        lease = self._leases.get(side)
        if lease is not None and self._motors[side].enabled and not self._halted.is_set():
            hold(f"motor-{side}", lease[1], DEADMAN_GRACE_WALL_S)
        else:
            unhold(f"motor-{side}")

    def halt(self) -> None:
        """End the world at once: both sides disabled where the car is now, and time stops.

        It does not first catch up with the clock, as `set_motor` does (a world that fell behind
        would otherwise go on driving the car for as long as the catch-up takes): an integration
        running in another thread stops after its current step, and from now on `advance_to` does
        nothing. Thread-safe and idempotent; the simulator calls it whenever a run ends.
        """
        self._halted.set()
        halt_clock = getattr(self.clock, "halt", None)
        if halt_clock is not None:
            halt_clock()  # the clock stops too: the run's figures are those of this moment
        with self._lock:
            for side, channel in self._motors.items():
                channel.enabled = False
                channel.duty_percent = 0.0
                self._hold_clock(side)

    @property
    def halted(self) -> bool:
        """`halt()` was called: the world's time no longer moves."""
        return self._halted.is_set()

    def set_servo(self, degrees: float) -> None:
        """Command the sonar servo; it turns there at `servo_deg_per_s`."""
        if not 0 <= degrees <= self.car.servo_max_deg:
            raise ValueError(f"servo angle must be 0..{self.car.servo_max_deg:g}°, got {degrees}")
        with self._lock:
            self._sync()
            self._servo.target_deg = float(degrees)

    def time_s(self) -> float:
        """Sim time: the clock's (the world may integrate a little behind it), else the world's."""
        if self.clock is not None:
            return self.clock.now()
        with self._lock:
            return self._time

    def servo_angle_deg(self) -> float:
        """The servo's current (not commanded) angle."""
        with self._lock:
            self._sync()
            return self._servo.angle_deg

    def read_sonar_cm(self, charge: bool = True) -> int | None:
        """One HC-SR04 ping: whole centimetres within 2..400, or None when no echo returns.

        Each of `sonar_rays` rays across the beam ends at the first wall it meets; it echoes only
        when it meets that wall within `sonar_max_incidence_deg` of the wall's normal (a wall hit
        more obliquely reflects the sound away). The nearest echo is the reading; then the
        optional noise, and with probability `sonar_drop` the echo is lost (seeded).
        With a clock that can be charged (`SimClock`), the ping takes its robot time: the wait for
        the 60 ms ping interval, then the echo's flight (or the 38 ms time-out). `charge=False`:
        the reading at this moment, taking no robot time (a ROS 2 range driver that publishes on
        its own, `umlbot.sim.ros2_world`).
        """
        with self._lock:
            self._sync()
            wait = self.car.sonar_interval_s - (self._time - self._last_ping_s)
        if wait > 0 and charge:  # outside the lock: the other lanes' commands go on meanwhile
            self._charge(wait)
        with self._lock:
            self._sync()
            origin, bearing = self._sonar_origin()
            echo = self._echo(origin, bearing)
            result: int | None = None
            if echo is not None:
                cm = echo[0] * 100.0
                if self.sonar_noise_cm > 0:
                    cm += self._rng.gauss(0.0, self.sonar_noise_cm)
                dropped = self.sonar_drop > 0 and self._rng.random() < self.sonar_drop
                if not dropped and cm <= self.car.sonar_max_cm:
                    result = max(self.car.sonar_min_cm, round(cm))
            hit = None
            if result is not None and echo is not None:
                hit = Point(origin.x + echo[0] * math.cos(echo[1]), origin.y + echo[0] * math.sin(echo[1]))
            if charge:  # a free-running driver's readings would crowd the trace's pings
                self._trace.pings.append(Ping(self._time, origin, bearing, result, hit))
                self._trace.pings_total += 1
                self._last_ping_s = self._time
        echo_s = self.car.sonar_timeout_s if result is None else 2 * result / 100.0 / SPEED_OF_SOUND_MPS
        if charge:
            self._charge(echo_s)
        return result

    def _echo(self, origin: Point, bearing: float) -> tuple[float, float] | None:
        """The nearest echo across the beam: (metres, the direction of its ray), or None."""
        half = math.radians(self.car.sonar_beam_deg) / 2
        n = max(1, self.car.sonar_rays)
        offsets = [0.0] if n == 1 else [-half + 2 * half * i / (n - 1) for i in range(n)]
        steepest = math.radians(self.car.sonar_max_incidence_deg)
        echoes = []
        for offset in offsets:
            hit = self._index.cast_hit(origin, bearing + offset)
            if hit is not None and incidence(bearing + offset, hit[1]) <= steepest:
                echoes.append((hit[0], bearing + offset))
        return min(echoes, default=None)

    def render_stereo(self, width_px: int, height_px: int) -> StereoImages:
        """The stereo camera's left and right images from where the car is now (`umlbot.sim.camera`).

        The camera sits at the front of the car, looking straight ahead; `SimError` when it has
        been stopped (`camera_stopped`). While the car stands still the picture is the same one
        (no new sensor noise), so a driver can tell that nothing changed.
        """
        if not (16 <= width_px <= 4096 and 16 <= height_px <= 4096):
            raise ValueError(f"image size must be 16..4096 pixels a side, got {width_px}x{height_px}")
        if self.camera_stopped:
            raise SimError("the stereo camera delivers no frames (stopped)")
        from umlbot.sim.camera import CameraRenderer, StereoRig

        with self._lock:
            self._sync()
            pose, now = self._pose, self._time
            last = self._last_picture
            if last is not None and last[0] == (width_px, height_px) and _same_place(last[1], pose):
                return last[2]._replace(time_s=now)  # the car stood still: the same picture
            renderer = self._renderers.get((width_px, height_px))
            if renderer is None:
                renderer = CameraRenderer(self._walls, StereoRig().scaled(width_px, height_px),
                                          seed=self._camera_seed)
                self._renderers[(width_px, height_px)] = renderer
        left, right = renderer.render(pose)  # outside the lock: the other lanes go on
        rig = renderer.rig
        images = StereoImages(now, width_px, height_px, rig.focal_px, rig.baseline_m,
                              left.tobytes(), right.tobytes())
        with self._lock:
            self._last_picture = ((width_px, height_px), pose, images)
        return images

    # --- integration ---------------------------------------------------------------------------

    def advance_to(self, time_s: float) -> None:
        """Integrate in fixed steps, then one partial step, until the world's time is `time_s`.

        The partial step puts the world exactly at the time a command arrives, so a motor runs
        for exactly as long as it was told to, not rounded to the step.
        """
        halted = self._halted
        step_s = self.step_s
        with self._lock:
            while True:  # the steps end on a fixed grid of sim time, whoever asks for them
                boundary = (math.floor(self._time / step_s + 1e-6) + 1) * step_s
                if boundary > time_s + 1e-12:
                    break
                if halted.is_set():
                    return
                self._step_to_lease_end(boundary)
                self.step(boundary - self._time)
            self._step_to_lease_end(time_s)
            rest = time_s - self._time
            if rest > 1e-9 and not halted.is_set():
                self.step(rest)

    def _step_to_lease_end(self, before: float) -> None:
        """When a driving side's lease ends before `before`, step to that moment first: the
        deadman stops the motor at its exact time, not at the next step (only then is the grid
        split; a run without a deadman stop integrates the same steps)."""
        ends = [end for side, (_, end) in self._leases.items()
                if self._motors[side].enabled and self._time + 1e-9 < end < before - 1e-9]
        if ends:
            self.step(min(ends) - self._time)

    def step(self, dt: float) -> None:
        """Advance the world by `dt` sim seconds: deadman, motors, servo, pose, collision, goal."""
        with self._lock:
            self._deadman()
            car = self.car
            # exact for a constant target: a step split in two ends where the whole step does
            alpha = 1.0 if car.motor_time_constant_s <= 0 else -math.expm1(-dt / car.motor_time_constant_s)
            for channel in self._motors.values():
                target = 0.0
                if channel.enabled and channel.duty_percent >= car.dead_band_percent:
                    target = car.top_speed_mps * channel.duty_percent / 100.0
                    target = target if channel.forward else -target
                channel.speed_mps += (target - channel.speed_mps) * alpha
            servo = self._servo
            max_turn = car.servo_deg_per_s * dt
            delta = servo.target_deg - servo.angle_deg
            servo.angle_deg += max(-max_turn, min(max_turn, delta))

            v_left, v_right = self._motors["left"].speed_mps, self._motors["right"].speed_mps
            v = (v_left + v_right) / 2
            omega = (v_right - v_left) / car.turn_track_m
            x, y, heading = self._pose
            mid = heading + omega * dt / 2  # midpoint rule: exact enough for 5 ms steps
            candidate = Pose(x + v * math.cos(mid) * dt, y + v * math.sin(mid) * dt, heading + omega * dt)
            self._time += dt
            moved = candidate != self._pose
            if moved and self.hits_wall(candidate):
                if not self._in_contact:
                    self._collisions += 1
                    self._trace.collision_points.append((x, y))
                    log.info("collision", time_s=round(self._time, 3), x=round(x, 3), y=round(y, 3))
                    if self.max_collisions is not None and self._collisions >= self.max_collisions:
                        self.halt()
                self._in_contact = True
                self._last_contact_s = self._time
                for channel in self._motors.values():
                    channel.speed_mps = 0.0  # the wall stops the car
                return
            if moved:
                if self._time - self._last_contact_s >= CONTACT_SETTLE_S:
                    self._in_contact = False
                self._distance += math.hypot(candidate.x - x, candidate.y - y)
                self._pose = candidate
                last = self._trace.path[-1]
                if math.hypot(candidate.x - last[1], candidate.y - last[2]) >= 0.005:
                    self._trace.path.append((self._time, candidate.x, candidate.y))
                if self.track.goal.contains(candidate.x, candidate.y):
                    self._goal_reached = True
                    if self.halt_at_goal:
                        self.halt()

    def _deadman(self) -> None:
        """Stop every enabled side whose lease ended by now (caller holds the lock)."""
        for side, (_, ends) in self._leases.items():
            channel = self._motors[side]
            if channel.enabled and self._time >= ends - 1e-9:
                channel.enabled = False
                channel.duty_percent = 0.0  # the deadman writes the pins low
                self._fired.add(side)
                self.deadman_stops.append((self._time, side))
                log.warning("motor_deadman", side=side, time_s=round(self._time, 3),
                            lease_ended_s=round(ends, 3))
                self._hold_clock(side)

    def _sync(self) -> None:
        if self.clock is not None:
            self.advance_to(self.clock.now())

    def _charge(self, sim_seconds: float) -> None:
        """Let `sim_seconds` pass for something the robot spends time on (only with a SimClock)."""
        charge = getattr(self.clock, "charge", None)
        if charge is not None:
            charge(sim_seconds)
            self._sync()

    # --- queries -------------------------------------------------------------------------------

    def hits_wall(self, pose: Pose) -> bool:
        """True when the car's footprint at `pose` touches a wall."""
        return self._index.rectangle_hits(rectangle_corners(pose, self.car.length_m, self.car.width_m))

    def _sonar_origin(self) -> tuple[Point, float]:
        x, y, heading = self._pose
        origin = Point(x + self.car.sonar_forward_m * math.cos(heading),
                       y + self.car.sonar_forward_m * math.sin(heading))
        return origin, heading + math.radians(self._servo.angle_deg - 90.0)

    def try_snapshot(self, wait_s: float) -> WorldSnapshot | None:
        """`snapshot()`, or None when the world stays busy (a long catch-up) for `wait_s` seconds."""
        if not self._lock.acquire(timeout=wait_s):
            return None
        try:
            return self.snapshot()
        finally:
            self._lock.release()

    def snapshot(self) -> WorldSnapshot:
        with self._lock:
            return WorldSnapshot(
                time_s=self._time,
                pose=self._pose,
                distance_m=self._distance,
                collisions=self._collisions,
                in_contact=self._in_contact,
                goal_reached=self._goal_reached,
                servo_deg=self._servo.angle_deg,
                left_speed_mps=self._motors["left"].speed_mps,
                right_speed_mps=self._motors["right"].speed_mps,
            )

    def motor(self, side: Side) -> MotorChannelState:
        """A copy of one side's channel state."""
        with self._lock:
            m = self._motors[side]
            return MotorChannelState(m.enabled, m.forward, m.duty_percent, m.speed_mps)

    @property
    def path(self) -> list[tuple[float, float, float]]:
        with self._lock:
            return list(self._trace.path)

    @property
    def pings(self) -> list[Ping]:
        """The newest pings of the run (at most `MAX_PINGS`)."""
        with self._lock:
            return list(self._trace.pings)

    def pings_since(self, seen: int) -> tuple[int, list[Ping]]:
        """(pings so far, the ones after the first `seen` that are still kept): a reader that polls
        copies only what is new, however long the run."""
        with self._lock:
            total = self._trace.pings_total
            new = min(total - seen, len(self._trace.pings))
            if new <= 0:
                return total, []
            newest_first = list(itertools.islice(reversed(self._trace.pings), new))
            return total, newest_first[::-1]

    @property
    def collision_points(self) -> list[tuple[float, float]]:
        with self._lock:
            return list(self._trace.collision_points)


def _same_place(a: Pose, b: Pose) -> bool:
    """Within a camera pixel's worth: 0.5 mm and 0.05° (a stopped car's speed decays, never to 0)."""
    return abs(a.x - b.x) < 5e-4 and abs(a.y - b.y) < 5e-4 and abs(a.heading - b.heading) < 1e-3


class WorldLoop:
    """A named thread that keeps the world's time up with the clock (fixed steps, catch-up)."""

    def __init__(self, world: World, clock: Clock, period_wall_s: float = 0.01) -> None:
        self.world = world
        self.clock = clock
        self.period_wall_s = period_wall_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="sim-world", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        step_s = self.world.step_s
        while not self._stop.wait(self.period_wall_s):
            # to the last grid point: the world loop adds no step boundary of its own, so the
            # world integrates the same steps however often (and whenever) the loop runs
            now = self.clock.now()
            self.world.advance_to(math.floor(now / step_s + 1e-6) * step_s)

    def stop(self) -> None:
        """Stop the loop; idempotent."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
