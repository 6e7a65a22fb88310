"""ROS 2 mappings as `umlbot check` sees them (type names, field paths, value types and ranges at
their file:line), golden CDR bytes of the shipped types checked with rosbags, and the names
ROS 2 puts on the wire."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from compiler_support import at, check_text, position

from umlbot.services.ros2 import dds
from umlbot.services.ros2.msgtypes import Types, dds_topic_name, dds_type_name

MODEL = """\
name: t
components:
  Base: {kind: actuator}
  Front: {kind: sensor}
  Lamp: {kind: ros2}
  Gripper: {kind: ros2}
deployment:
  driver: dds
  components:
    Base: {impl: ros2_twist, settings: {topic: /cmd_vel}}
    Front: {impl: ros2_range, settings: {topic: /front/range, stale_s: 0.5}}
    Lamp: {impl: ros2_setbool, settings: {service: /lamp/set}}
    Gripper:
      impl: ros2
      settings:
        features:
          open:
            params: [{name: width_m, type: float, min: 0, max: 0.08}]
            publish: {topic: /gripper/cmd, type: std_msgs/msg/Float64, fields: {data: width_m}}
          width:
            returns: float
            read: {topic: /gripper/width, type: std_msgs/msg/Float64, field: data}
          count:
            params: [{name: n, type: int, min: 0, max: 255}]
            publish: {topic: /gripper/count, type: std_msgs/msg/UInt8, fields: {data: n}}
lanes:
  - lane: Base
    nodes:
      - {id: start, kind: start}
      - {id: go, kind: action, call: "Base.drive(0.5, -1.0)"}
      - {id: d, kind: datastore, name: cm, value: Front.value()}
      - {id: on, kind: action, call: Lamp.set(true)}
      - {id: open, kind: action, call: Gripper.open(0.05)}
      - {id: w, kind: datastore, name: w, value: Gripper.width()}
      - {id: halt, kind: action, call: Base.stop()}
      - {id: end, kind: end}
"""


def test_a_model_with_ros2_components_compiles_with_their_features(tmp_path: Path) -> None:
    result = check_text(tmp_path, MODEL)
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.model is not None
    comps = result.model.components
    assert comps["Gripper"].features == ["count", "open", "width"]
    assert comps["Base"].features == ["drive", "stop"] and comps["Base"].service == "ros2"
    assert [s.feature for s in comps["Base"].safe_stop] == ["stop"], "the orchestrator stops the base"


@pytest.mark.parametrize(("old", "new", "needle", "message"), [
    ("type: std_msgs/msg/Float64, fields", "type: std_msgs/msg/Flaot64, fields", "publish:",
     "unknown message type 'std_msgs/msg/Flaot64'"),
    ("type: std_msgs/msg/Float64, field: data", "type: std_msgs/Float64, field: data", "read:",
     "ROS 2 names it 'std_msgs/msg/Float64'"),
    ("field: data}", "field: dta}", "read:", "no field 'dta' in 'std_msgs/msg/Float64'"),
    ("{name: n, type: int, min: 0, max: 255}", "{name: n, type: int, min: 0, max: 300}", "count:",
     "argument 'n' fills field 'data' (uint8, 0..255)"),
    ("{name: n, type: int, min: 0, max: 255}", "{name: n, type: str}", "count:",
     "argument 'n' (str) cannot fill field 'data' (uint8)"),
    ("returns: float", "returns: bool", "width:", "returns: bool, but field 'data' is a float"),
])
def test_a_wrong_mapping_is_reported_at_its_line(tmp_path: Path, old: str, new: str, needle: str,
                                                 message: str) -> None:
    text = MODEL.replace(old, new)
    assert text != MODEL
    result = check_text(tmp_path, text)
    assert not result.ok
    errors = [d for d in result.errors if message in d.message]
    assert errors, [str(d) for d in result.errors]
    assert at(errors[0])[0] == position(text, needle)[0], str(errors[0])


def test_feature_calls_are_checked_against_the_mapping(tmp_path: Path) -> None:
    text = MODEL.replace("Gripper.open(0.05)", "Gripper.open(0.5)").replace("Base.drive(0.5, -1.0)",
                                                                            "Base.drive(0.5)")
    result = check_text(tmp_path, text)
    messages = [d.message for d in result.errors]
    assert any("argument 1 (width_m) of Gripper.open must be 0..0.08" in m for m in messages), messages
    assert any("Base.drive takes 2 argument(s)" in m for m in messages), messages
    text = MODEL.replace("Lamp.set(true)", "Lamp.toggle()")
    result = check_text(tmp_path, text)
    assert any("does not offer feature 'toggle'" in d.message or "unknown feature 'toggle'" in d.message
               for d in result.errors), [d.message for d in result.errors]


def test_ros2_wire_names() -> None:
    assert dds_topic_name("/cmd_vel") == "rt/cmd_vel"
    assert dds_type_name("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    assert dds_type_name("std_srvs/srv/SetBool_Request") == "std_srvs::srv::dds_::SetBool_Request_"


#: little-endian CDR written out by hand from the definitions (encapsulation 00 01 00 00)
GOLDEN: dict[str, tuple[dict[str, Any], str]] = {
    "geometry_msgs/msg/Twist": (
        {"linear.x": 0.5, "angular.z": -1.25},
        "00010000" + "000000000000e03f" + "00" * 8 * 4 + "000000000000f4bf"),
    "sensor_msgs/msg/Range": (
        {"header.stamp.sec": 7, "header.frame_id": "x", "radiation_type": 0, "field_of_view": 0.25,
         "min_range": 0.02, "max_range": 4.0, "range": 1.5},
        "00010000" + "07000000" + "00000000" + "02000000" + "7800" + "00" + "00" + "0000803e"
        + "0ad7a33c" + "00008040" + "0000c03f"),
    "std_msgs/msg/String": ({"data": "hi"}, "00010000" + "03000000" + "686900"),
}


@pytest.mark.parametrize("typename", sorted(GOLDEN))
def test_golden_cdr_bytes_agree_with_rosbags(typename: str) -> None:
    types = Types.load()
    builder = dds.TypeBuilder.of(types)
    values, golden = GOLDEN[typename]
    sample = builder.default(typename)
    for path, value in values.items():
        dds.set_path(sample, path, value)
    ours = sample.serialize(use_version_2=False)
    assert ours.hex() == golden
    decoded = types.store.deserialize_cdr(bytes.fromhex(golden), typename)
    assert bytes(types.store.serialize_cdr(decoded, typename)).hex() == golden, "rosbags agrees"
    for path, value in values.items():
        got = decoded
        for part in path.split("."):
            got = getattr(got, part)
        assert got == pytest.approx(value)


def test_service_samples_carry_the_rmw_cyclonedds_header() -> None:
    types = Types.load()
    builder = dds.TypeBuilder.of(types)
    request = builder.default("std_srvs/srv/SetBool_Request", header=True)
    request.rmw_guid, request.rmw_seq, request.data = 0x0102030405060708, 9, True
    raw = request.serialize(use_version_2=False)
    assert raw.hex() == "00010000" + "0807060504030201" + "0900000000000000" + "01"
    body = types.store.deserialize_cdr(b"\x00\x01\x00\x00" + raw[20:], "std_srvs/srv/SetBool_Request")
    assert body.data is True


def test_a_signal_mapping_is_checked_too(tmp_path: Path) -> None:
    text = (Path(__file__).parent / "models" / "ros2_signals.yaml").read_text()
    assert check_text(tmp_path, text).ok
    bad = text.replace("type: std_msgs/msg/Float64, field: data}\n          done",
                       "type: std_msgs/msg/Float64, field: value}\n          done")
    assert bad != text
    result = check_text(tmp_path, bad)
    errors = [d for d in result.errors if "no field 'value' in 'std_msgs/msg/Float64'" in d.message]
    assert errors and at(errors[0])[0] == position(bad, "go: {direction")[0], \
        [str(d) for d in result.errors]


def test_the_users_own_message_types(tmp_path: Path) -> None:
    folder = tmp_path / "defs" / "grip_msgs"
    (folder / "msg").mkdir(parents=True)
    (folder / "srv").mkdir()
    (folder / "msg" / "Grip.msg").write_text("float32 width_m\nuint8 force\nstring mode\n")
    (folder / "srv" / "Close.srv").write_text("uint8 force\n---\nbool done\nfloat32 width_m\n")
    text = MODEL.replace("""        features:
          open:""", f"""        msg_paths: [{tmp_path / 'defs'}]
        features:
          grip:
            params: [{{name: force, type: int, min: 0, max: 100}}]
            publish:
              {{topic: /g, type: grip_msgs/msg/Grip, fields: {{force: force}}, constants: {{mode: soft}}}}
          close:
            params: [{{name: force, type: int, min: 0, max: 100}}]
            returns: float
            call: {{service: /g/close, type: grip_msgs/srv/Close, fields: {{force: force}}, reply: width_m}}
          open:""")
    result = check_text(tmp_path, text)
    assert result.ok, [str(d) for d in result.diagnostics]
    assert result.model is not None and result.model.components["Gripper"].features == [
        "close", "count", "grip", "open", "width"]
    bad = text.replace("reply: width_m", "reply: widht_m")
    errors = check_text(tmp_path, bad).errors
    assert any("no field 'widht_m' in 'grip_msgs/srv/Close_Response'" in d.message for d in errors), \
        [d.message for d in errors]


def test_without_the_extra_check_names_it(tmp_path: Path) -> None:
    import subprocess
    import sys

    (tmp_path / "model.yaml").write_text(MODEL)
    blocked = ("import sys; sys.modules['rosbags'] = None; sys.modules['cyclonedds'] = None; "
               "from umlbot.cli import main; main()")
    run = subprocess.run([sys.executable, "-c", blocked, "check", str(tmp_path / "model.yaml")],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 1
    assert "ROS 2 support is not installed (rosbags missing): pip install 'umlbot[ros2]'" in run.stdout
    line = position(MODEL, "Base: {impl: ros2_twist")[0]
    assert f"model.yaml:{line}:" in run.stdout, run.stdout
