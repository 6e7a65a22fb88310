"""`umlbot studio MODEL --robot '*'`: the fleet view's requests, `GET /api/fleet` and
`POST /api/fleet/follow`, on a real broker (the page itself: test_fleet_studio_browser.py)."""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

from conftest import BrokerProcess, RawClient, wait_until
from robot_run import CAR_MODEL
from studio_support import studio

STATUS = '{"state":"online","impl":"l298n","features":["dutycycle"]}'


def request(url: str, body: dict[str, Any] | None = None,
            headers: dict[str, str] | None = None) -> tuple[int, Any]:
    data = json.dumps(body).encode() if body is not None else None
    sent = {"Content-Type": "application/json", **(headers or {})}
    req = urllib.request.Request(url, data=data, headers=sent)  # noqa: S310 (http on loopback)
    try:
        with urllib.request.urlopen(req, timeout=10) as answer:  # noqa: S310 (http on loopback)
            return answer.status, json.loads(answer.read())
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read().decode(errors="replace")


def test_fleet_requests_list_robots_and_follow_one(
        mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path) -> None:
    publisher = raw_client(mosquitto_broker)
    publisher.publish("umlbot/fleet-x1/LeftActuator/status", STATUS, retain=True)
    publisher.publish("umlbot/fleet-x1/orchestrator/status",
                      '{"state":"failed","reason":"LeftActuator timed out"}', retain=True)
    try:
        args = ["studio", str(CAR_MODEL), "--broker", mosquitto_broker.url, "--robot", "*", "--port", "0"]
        with studio(args, tmp_path) as proc:
            api = proc.url + "api/fleet"
            seen: dict[str, Any] = {}

            def listed() -> bool:
                status, body = request(api)
                assert status == 200, body
                seen.update({r["robot"]: r for r in body["robots"]})
                # both retained messages seen (the broker may hand them over in either order)
                return (body["hub"]["connected"] and "fleet-x1" in seen and seen["fleet-x1"]["components"]
                        and seen["fleet-x1"]["orchestrator"] != "unknown")

            assert wait_until(listed, timeout=20), seen
            row = seen["fleet-x1"]
            assert row["components"] == {"LeftActuator": "online"}
            assert row["orchestrator"] == "failed"
            assert row["faults"] == ["run failed: LeftActuator timed out"]
            # a page of another origin may not make the studio follow a robot
            status, _ = request(api + "/follow", {"robot": "fleet-x1"}, {"Origin": "http://evil.example"})
            assert status == 403
            status, body = request(api + "/follow", {"robot": "no/such robot"})
            assert status == 400
            status, body = request(api + "/follow", {"robot": "fleet-x1"})
            assert status == 200 and body == {"followed": "fleet-x1"}
            assert request(api)[1]["followed"] == "fleet-x1"
    finally:
        for topic in ("LeftActuator/status", "orchestrator/status"):
            publisher.publish(f"umlbot/fleet-x1/{topic}", "", retain=True)
