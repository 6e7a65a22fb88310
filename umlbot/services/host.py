"""Running one hardware service: every component of one service kind in a deployment, on the bus.

`ServiceHost(kind, deployment, settings, robot, driver=None)` builds each component's driver
through the registry (driver name: `driver` if given, else the deployment's choice), serves the
implementation's features on its own bus connection (one last will per component), publishes
the retained `state` after every change, and guarantees the safe stops:

- every component is put into its safe state (`ComponentService.safe_stop`: motors stopped,
  servos limp) when the host stops (any exit path: `stop()`, context manager exit, signals in
  `umlbot service`) and when the broker connection is lost;
- the components of a service kind whose spec says `stop_when_orchestrator_offline` (motor, and
  any plugin's kind that sets it) also when `umlbot/<robot>/orchestrator/status` says `offline`
  (its last will), `stopped` or `failed`; motors also when their watchdog expires. The same
  kinds hear the orchestrator's heartbeat (`ComponentService.orchestrator_heartbeat`: a motor
  it commanded runs on while it comes), and every component's `tick` runs every `TICK_S`.

`host.drivers[component]` is the driver object, so tests can read a mock driver's commands.
`ServiceGroup` runs several kinds in one process (`umlbot service all`, for small boards).
"""

from __future__ import annotations

import importlib
import threading
import time
from collections.abc import Mapping
from typing import Any

from umlbot.base import sdnotify
from umlbot.base.catalog import service_kinds, service_spec
from umlbot.base.deployment import Deployment, owned_pins, shared_pins
from umlbot.base.errors import ConfigError, DriverError, UnknownDriver
from umlbot.base.library import ServiceKind
from umlbot.base.logs import get_logger
from umlbot.base.registry import SettingsError, create_driver, resolve_driver
from umlbot.base.topics import Topics
from umlbot.services.bus import STATUS_WAIT_S, BrokerSettings, ComponentServer, Heartbeat, Message, parse_json
from umlbot.services.component_service import ComponentService

log = get_logger("umlbot.host")

#: Orchestrator states after which no motor may keep running.
ORCHESTRATOR_STOP_STATES = frozenset({"offline", "stopped", "failed"})
#: Every state an orchestrator status may say (`OrchestratorStatus.state`).
ORCHESTRATOR_STATES = frozenset({"starting", "running", "stopping", "stopped", "failed", "offline"})
#: an unreadable orchestrator status is logged at most once in this many seconds.
BAD_STATUS_WARN_EVERY_S = 10.0

TICK_S = 0.05


def _service_class(kind: ServiceKind) -> type[ComponentService]:
    spec = service_spec(kind)
    if spec is None:
        raise ConfigError(f"unknown service kind {kind!r}; known: {', '.join(service_kinds())}")
    module_name, _, attribute = spec.service.partition(":")
    try:
        cls: Any = getattr(importlib.import_module(module_name), attribute)
    # a plugin's service class that does not load (or exits at import): name it, no traceback
    except (Exception, SystemExit) as exc:
        from umlbot.base.plugins import catalog

        package = catalog().origin.get(f"service:{kind}", "?")
        raise ConfigError(f"the {kind} service of package {package} cannot be loaded from "
                          f"{spec.service}: {type(exc).__name__}: {exc}") from exc
    if not (isinstance(cls, type) and issubclass(cls, ComponentService)):
        raise ConfigError(f"the {kind} service: {spec.service} is not a umlbot.services.component_service."
                          "ComponentService subclass")
    return cls


class ServiceHost:
    """Serves every component of one service kind; `start()`/`stop()` (idempotent), or `with`."""

    def __init__(
        self,
        kind: ServiceKind,
        deployment: Deployment,
        settings: BrokerSettings,
        robot: str,
        driver: str | None = None,
        *,
        components: list[str] | None = None,
        connect_timeout_s: float = 5.0,
    ) -> None:
        if service_spec(kind) is None:
            raise ConfigError(f"unknown service kind {kind!r}; known: {', '.join(service_kinds())}")
        self.kind = kind
        self.deployment = deployment
        self.settings = settings
        self.robot = robot
        self.topics = Topics(robot)
        self.driver_override = driver
        self.connect_timeout_s = connect_timeout_s
        served = deployment.components_of_service(kind)
        if components is not None:
            unknown = sorted(set(components) - set(served))
            if unknown:
                raise ConfigError(f"no {kind} component(s) {unknown} in the deployment")
            served = {name: comp for name, comp in served.items() if name in components}
        if not served:
            raise ConfigError(f"the deployment has no component served by the {kind} service")
        for shared in shared_pins(deployment):
            if shared.component in served or shared.first in served:  # `umlbot check` refuses it too
                at = deployment.where("components", shared.component, "settings", *shared.path)
                raise ConfigError(f"{at}: {shared.message()}")
        self.component_deployments = served
        self.drivers: dict[str, Any] = {}
        #: component -> the driver that runs it (`auto` resolved), filled in as the drivers are built
        self.chosen_drivers: dict[str, str] = {}
        self.services: dict[str, ComponentService] = {}
        self.servers: dict[str, ComponentServer] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        self._started = False
        self._serving = False  # start() succeeded
        self._stopped = False
        self._bad_status_warned = -BAD_STATUS_WARN_EVERY_S
        #: `time.monotonic()` of the safety loop's last round (`alive`)
        self.last_tick = time.monotonic()

    # -- lifecycle ----------------------------------------------------------------------------------

    def driver_name(self, component: str) -> str:
        """The driver a component runs with: `--driver`, else the deployment's choice."""
        return self.driver_override or self.deployment.driver_for(component)

    def _driver_settings(self, component: str) -> dict[str, Any]:
        settings = dict(self.component_deployments[component].settings)
        if self.kind == "gpio":
            reserved = {
                pin: owner for pin, owner in owned_pins(self.deployment).items() if owner != component
            }
            # a listed pin another component owns was refused in __init__ (`shared_pins`)
            settings["reserved_pins"] = {**reserved, **settings.get("reserved_pins", {})}
        return settings

    def start(self) -> None:
        """Build the drivers, connect every component and start the safety watch.

        On any failure everything built so far is stopped again (motors stopped) and the error
        is raised: `ConfigError`, `UnknownDriver`, `DriverError` or `NotConnected`.
        """
        with self._lock:
            if self._started:
                return
            self._started = True
        try:
            self._build()
            self._watch_orchestrator()
            for server in self.servers.values():
                server.connect(self.connect_timeout_s)  # returns once the broker confirmed the subscriptions
            # the retained statuses arrive together: one short wait for all of them
            deadline = time.monotonic() + STATUS_WAIT_S
            for name, server in self.servers.items():
                server.claim(max(0.0, deadline - time.monotonic()), self.connect_timeout_s)
                self.services[name].changed()
            self._ticker = threading.Thread(
                target=self._tick_loop, name=f"{self.kind}-safety", daemon=True
            )
            self._ticker.start()
        except BaseException:
            self.stop()
            raise
        self._serving = True
        # the drivers that run, `auto` resolved (`driver_auto` says why it chose that one)
        log.info("service_started", kind=self.kind, robot=self.robot,
                 components={n: self.chosen_drivers[n] for n in self.services}, broker=self.settings.url)

    def _build(self) -> None:
        service_cls = _service_class(self.kind)
        for name, comp in self.component_deployments.items():
            driver = self._create_driver(name)
            self.drivers[name] = driver
            service = service_cls(name, comp.implementation, driver, comp.settings)
            self.services[name] = service
            server = ComponentServer(self.settings, self.robot, name, comp.implementation.id,
                                     service.features(), driver=self.chosen_drivers[name])
            service.publish_state = server.publish_state
            service.on_server(server)
            # Re-publish the retained state after a reconnect (the broker may have restarted).
            server.connection.add_on_connect(service.changed)
            server.connection.add_on_disconnect(self._on_disconnect_of(service))
            self.servers[name] = server

    def _create_driver(self, name: str) -> Any:
        """The component's driver; a deployment mistake names its `file:line:col`."""
        dep = self.deployment
        try:
            driver = create_driver(self.kind, self.driver_name(name), name, self._driver_settings(name))
            self.chosen_drivers[name] = resolve_driver(self.driver_name(name))
            return driver
        except SettingsError as exc:
            path, message = exc.problems[0]
            more = len(exc.problems) - 1
            also = f" (and {more} more problem{'s' if more > 1 else ''})" if more else ""
            dotted = ".".join(str(p) for p in ("settings", *path))
            raise SettingsError(name, exc.problems,
                                f"{dep.where('components', name, 'settings', *path)}: component {name}: "
                                f"{dotted}: {message}{also}") from None
        except UnknownDriver as exc:
            at = ("components", name, "driver") if dep.components[name].driver else ("driver",)
            raise UnknownDriver(f"{dep.where(*at)}: {exc}") from None

    def _on_disconnect_of(self, service: ComponentService) -> Any:
        def lost() -> None:
            if not self._stop.is_set():
                service.safe_stop("broker connection lost")

        return lost

    def _watch_orchestrator(self) -> None:
        if not _stops_first(self.kind) or not self.servers:
            return
        first = next(iter(self.servers.values()))
        first.connection.subscribe(self.topics.orchestrator_status, self._on_orchestrator_status)
        first.connection.subscribe(self.topics.orchestrator_heartbeat, self._on_heartbeat, qos=0)

    def _on_heartbeat(self, message: Message) -> None:
        if message.retain:  # a retained heartbeat is an old one: no sign of life
            return
        try:
            beat = Heartbeat.model_validate_json(message.payload)
        except ValueError:  # not a heartbeat: no renewal (whoever sent it, the motors stop in time)
            log.debug("heartbeat_unreadable", size=len(message.payload))
            return
        for service in list(self.services.values()):
            service.orchestrator_heartbeat(beat.reply_to)

    def _on_orchestrator_status(self, message: Message) -> None:
        state: Any
        if not message.payload.strip():  # a retained status cleared (`mosquitto_pub -r -n`)
            return
        try:
            data = parse_json(message.payload)
        except ValueError:
            data = message.payload.decode("utf-8", "replace").strip()  # `-m offline` works too
        state = data.get("state") if isinstance(data, dict) else data
        if not isinstance(state, str) or state not in ORCHESTRATOR_STATES:
            # whether the orchestrator still runs is unknown: stop, as for a stopped one
            now = time.monotonic()
            if now - self._bad_status_warned >= BAD_STATUS_WARN_EVERY_S:
                self._bad_status_warned = now
                log.warning("orchestrator_status_unreadable", topic=message.topic,
                            payload=message.payload[:80].decode("utf-8", "replace"),
                            size=len(message.payload), action="components stopped")
            self.safe_stop_all("orchestrator status unreadable")
            return
        if state in ORCHESTRATOR_STOP_STATES:
            self.safe_stop_all(f"orchestrator {state}")

    def safe_stop_all(self, reason: str) -> None:
        """Put every served component into its safe state (motors stopped)."""
        for service in list(self.services.values()):
            try:
                service.safe_stop(reason)
            except Exception:
                log.exception("safe_stop_failed", component=service.component, reason=reason)

    def _tick_loop(self) -> None:
        while not self._stop.wait(TICK_S):
            now = self.last_tick = time.monotonic()
            for service in list(self.services.values()):
                try:
                    service.tick(now)
                except Exception:
                    log.exception("tick_failed", component=service.component)

    def stop(self) -> None:
        """Stop the hardware safely first, then go offline and release the drivers; idempotent."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
        self._stop.set()
        # Safety first: motors stop before anything that might hang (network, joins).
        self.safe_stop_all("service stopping")
        for server in self.servers.values():
            try:
                server.stop()
            except Exception:
                log.exception("server_stop_failed", component=server.component)
        for service in self.services.values():
            service.close()
        for name, driver in self.drivers.items():
            if name not in self.services:  # built, but its service was not
                try:
                    driver.close()
                except Exception:
                    log.exception("driver_close_failed", component=name)
        # is_alive: a signal (KeyboardInterrupt) inside Thread.start() leaves a thread that
        # join() refuses ("cannot join thread before it is started"); it sees _stop and ends
        ticker = self._ticker
        if ticker is not None and ticker.is_alive() and ticker is not threading.current_thread():
            ticker.join(timeout=2.0)
        if self._serving:  # a failed start says why in its error, not in a "stopped" line
            log.info("service_stopped", kind=self.kind, robot=self.robot)

    def __enter__(self) -> ServiceHost:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def alive(self, within_s: float) -> bool:
        """The safety loop (watchdogs, renewals) went round within the last `within_s` seconds."""
        return self._serving and time.monotonic() - self.last_tick <= within_s

    @property
    def components(self) -> Mapping[str, ComponentService]:
        """The served components by name."""
        return self.services


def _stops_first(kind: ServiceKind) -> bool:
    """Whether a kind's parts must not run on without the orchestrator (motors; its spec's
    `stop_when_orchestrator_offline`): its host watches the orchestrator's status, and it starts
    and stops first in a `ServiceGroup`."""
    spec = service_spec(kind)
    return spec is not None and spec.stop_when_orchestrator_offline


class ServiceGroup:
    """Several service kinds in one process: one `ServiceHost` per kind the deployment uses.

    `umlbot service all` on a small board: one interpreter instead of four (each is most of a
    service's memory). Every component keeps its own connection and last will, and each host
    its safety stops; `stop()` stops the motors (the kinds that stop when the orchestrator goes
    offline) first. `start()`/`stop()` (idempotent), or `with`.
    """

    def __init__(
        self,
        kinds: tuple[ServiceKind, ...],
        deployment: Deployment,
        settings: BrokerSettings,
        robot: str,
        driver: str | None = None,
        *,
        components: list[str] | None = None,
        connect_timeout_s: float = 5.0,
    ) -> None:
        if len(kinds) == 1:  # one kind: its host says what is wrong with the components asked for
            self.hosts = [ServiceHost(kinds[0], deployment, settings, robot, driver,
                                      components=components, connect_timeout_s=connect_timeout_s)]
            return
        served = {kind: deployment.components_of_service(kind) for kind in kinds}
        if components is not None:
            unknown = sorted(set(components) - {name for names in served.values() for name in names})
            if unknown:
                raise ConfigError(f"no component(s) {unknown} in the deployment")
            served = {kind: {name: comp for name, comp in comps.items() if name in components}
                      for kind, comps in served.items()}
        self.hosts = [
            ServiceHost(kind, deployment, settings, robot, driver,
                        components=list(comps), connect_timeout_s=connect_timeout_s)
            for kind, comps in sorted(served.items(), key=lambda item: not _stops_first(item[0]))
            if comps
        ]
        if not self.hosts:
            raise ConfigError("the deployment has no component served by any service")

    def start(self) -> None:
        """Start every host; on a failure stop those started (motors stopped) and raise."""
        try:
            for host in self.hosts:
                host.start()
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        """Stop every host, the motors' (`_stops_first`) first; idempotent."""
        for host in self.hosts:
            host.stop()

    def __enter__(self) -> ServiceGroup:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def wait(self, stop: threading.Event) -> None:
        """Block until `stop` is set (the CLI sets it from SIGTERM/SIGINT).

        Under systemd (`Type=notify`) it says `READY=1` first and `STOPPING=1` at the end, and
        with `WatchdogSec=` it says `WATCHDOG=1` every quarter of that time while the safety
        loop of every host (watchdogs, deadman renewals) went round within half of it: a frozen
        or hung service stops saying it, and systemd kills it (docs/services.md, Safety).
        """
        timeout = sdnotify.watchdog_s()
        sdnotify.notify("READY=1")
        period = 0.5 if timeout is None else min(0.5, timeout / 4)
        while not stop.wait(period):
            if timeout is not None and all(host.alive(timeout / 2) for host in self.hosts):
                sdnotify.notify("WATCHDOG=1")
        sdnotify.notify("STOPPING=1")

    def safe_stop_hardware(self) -> None:
        """Without the bus: build every served component's driver and close it, which leaves it
        in its safe state (motors: pins low; pigpio: a killed predecessor's deadman script
        deleted). `umlbot service KIND --safe-stop`, the units' `ExecStopPost=`, after any end
        of the service, SIGKILL and a watchdog kill included. Raises `DriverError` naming every
        component it could not stop, after trying them all."""
        problems: list[str] = []
        for host in self.hosts:
            for name in host.component_deployments:
                try:
                    host._create_driver(name).close()
                except Exception as exc:
                    problems.append(f"{name}: {exc}")
                    continue
                log.info("safe_stop_done", component=name, driver=host.chosen_drivers[name])
        if problems:
            raise DriverError("safe stop failed: " + "; ".join(problems))

    @property
    def components(self) -> Mapping[str, ComponentService]:
        """The served components of every kind, by name."""
        return {name: service for host in self.hosts for name, service in host.services.items()}
