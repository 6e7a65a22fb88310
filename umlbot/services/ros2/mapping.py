"""A ROS 2 component's deployment settings: which topic or service each feature reads, writes or
calls, checked against the message definitions (type names, field paths, value types and
ranges) so that `umlbot check` reports a mistake at its file:line.

Every ROS 2 implementation is served by the `ros2` service kind. The presets fill in the
features from a few settings; `ros2` (the generic one) takes them from `features`:

    FrontRange: {impl: ros2_range, driver: dds, settings: {topic: /front/range}}
    Base:       {impl: ros2_twist, driver: dds, settings: {topic: /cmd_vel}}
    Lamp:       {impl: ros2_setbool, driver: dds, settings: {service: /lamp/set}}
    Gripper:
      impl: ros2
      driver: dds
      settings:
        msg_paths: [msg]                       # <package>/msg/<Name>.msg, <package>/srv/<Name>.srv
        features:
          open:
            params: [{name: width_m, type: float, min: 0, max: 0.08}]
            publish: {topic: /gripper/cmd, type: std_msgs/msg/Float64, fields: {data: width_m}}
          width:
            returns: float
            read: {topic: /gripper/width, type: std_msgs/msg/Float64, field: data}
          reset:
            returns: bool
            call: {service: /gripper/reset, type: std_srvs/srv/Trigger, reply: success}
"""

from __future__ import annotations

import math
import os
import threading
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from umlbot.base.library import ArgType, FeatureSpec, Implementation, Param, ValueType
from umlbot.services.ros2.msgtypes import BASE_TYPES, Types, check_value

TOPIC = r"^/?[A-Za-z_~{][A-Za-z0-9_/{}~]*$"

_context = threading.local()


def _types() -> Types:
    """The definitions the settings being validated see (their `msg_paths`)."""
    return Types.load(getattr(_context, "msg_paths", ()))


class ParamDecl(BaseModel):
    """An argument of a generic feature."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    type: ArgType
    min: float | None = None
    max: float | None = None
    unit: str = ""

    def param(self) -> Param:
        return Param(self.name, self.type, self.min, self.max, self.unit)


class TopicRead(BaseModel):
    """A feature returning a field of the latest message on a topic (times `scale`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    topic: str = Field(pattern=TOPIC)
    type: str
    field: str
    scale: float = 1.0
    stale_s: float = Field(default=1.0, gt=0, description="older than this: a `stale` error reply")
    first_s: float = Field(default=2.0, ge=0, description="wait this long for a first message")
    reliable: bool = False

    @model_validator(mode="after")
    def _check(self) -> TopicRead:
        types = _types()
        types.check_message(self.type)
        found = types.scalar_field(self.type, self.field)
        if found.value_type == "str" and self.scale != 1.0:
            raise ValueError(f"field '{self.field}' is a string: it cannot be scaled")
        return self


class TopicWrite(BaseModel):
    """A feature publishing one message: `fields` maps field paths to the feature's arguments,
    `constants` sets fields to fixed values; the rest stay zero."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    topic: str = Field(pattern=TOPIC)
    type: str
    fields: dict[str, str] = Field(default_factory=dict)
    constants: dict[str, bool | int | float | str] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _check(self) -> TopicWrite:
        _check_fields(self.type, self.fields, self.constants, message=True)
        return self


class ServiceCall(BaseModel):
    """A feature calling a ROS 2 service: `fields`/`constants` fill the request, `reply` names
    the response's field the feature returns."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    service: str = Field(pattern=TOPIC)
    type: str
    fields: dict[str, str] = Field(default_factory=dict)
    constants: dict[str, bool | int | float | str] = Field(default_factory=dict)
    reply: str | None = None
    timeout_s: float = Field(default=2.0, gt=0, le=60)

    @model_validator(mode="after")
    def _check(self) -> ServiceCall:
        types = _types()
        types.check_service(self.type)
        _check_fields(f"{self.type}_Request", self.fields, self.constants, message=False)
        if self.reply is not None:
            types.scalar_field(f"{self.type}_Response", self.reply)
        return self


def _check_fields(typename: str, fields: dict[str, str], constants: dict[str, Any], message: bool) -> None:
    types = _types()
    if message:
        types.check_message(typename)
    for path in fields:
        types.scalar_field(typename, path)
    for path, value in constants.items():
        check_value(value, types.scalar_field(typename, path))


class FeatureMap(BaseModel):
    """One feature of a ROS 2 component: its arguments, what it returns and exactly one of
    `read`, `publish`, `call`."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    params: list[ParamDecl] = Field(default_factory=list)
    returns: ValueType = "none"
    read: TopicRead | None = None
    publish: TopicWrite | None = None
    call: ServiceCall | None = None
    doc: str = ""

    @model_validator(mode="after")
    def _check(self) -> FeatureMap:
        chosen = [name for name in ("read", "publish", "call") if getattr(self, name) is not None]
        if len(chosen) != 1:
            raise ValueError(f"a feature has exactly one of read, publish, call (got "
                             f"{', '.join(chosen) or 'none'})")
        params = {p.name: p for p in self.params}
        types = _types()
        if self.read is not None:
            if self.params:
                raise ValueError("a 'read' feature takes no arguments")
            found = types.scalar_field(self.read.type, self.read.field)
            _check_returns(self.returns, found.value_type, self.read.field)
        target = self.publish or self.call
        if target is not None:
            typename = target.type if self.publish is not None else f"{target.type}_Request"
            for path, name in target.fields.items():
                if name not in params:
                    raise ValueError(f"field '{path}' takes argument '{name}', which is not among the "
                                     f"params ({', '.join(params) or 'none'})")
                _check_param_fits(params[name], types.scalar_field(typename, path).base or "string", path)
            unused = sorted(set(params) - set(target.fields.values()))
            if unused:
                raise ValueError(f"argument(s) {unused} fill no field (map them in 'fields')")
        if self.publish is not None and self.returns != "none":
            raise ValueError("a 'publish' feature returns nothing (returns: none)")
        if self.call is not None:
            if self.call.reply is None and self.returns != "none":
                raise ValueError("name the response field it returns ('reply'), or returns: none")
            if self.call.reply is not None:
                found = types.scalar_field(f"{self.call.type}_Response", self.call.reply)
                _check_returns(self.returns, found.value_type, self.call.reply)
        return self

    def spec(self, name: str) -> FeatureSpec:
        return FeatureSpec(name, tuple(p.param() for p in self.params), self.returns, self.doc)


def _check_returns(returns: ValueType, field_type: ArgType | None, path: str) -> None:
    fits = {"none": True, "str": field_type == "str", "bool": field_type == "bool",
            "int": field_type in ("int", "float"), "float": field_type in ("int", "float")}
    if not fits[returns]:
        raise ValueError(f"returns: {returns}, but field '{path}' is a {field_type}")


def _check_param_fits(param: ParamDecl, base: str, path: str) -> None:
    field_type, low, high = BASE_TYPES[base]
    fits = param.type == field_type or (param.type == "int" and field_type == "float")
    if not fits:
        raise ValueError(f"argument '{param.name}' ({param.type}) cannot fill field '{path}' ({base})")
    if low is None or high is None:
        return
    if param.min is None or param.max is None or param.min < low or param.max > high:
        raise ValueError(f"argument '{param.name}' fills field '{path}' ({base}, {low:g}..{high:g}): "
                         f"give it min and max within that range")


class SignalMap(BaseModel):
    """A signal of the model carried on a ROS 2 topic. `to_ros`: every occurrence on
    `umlbot/<robot>/signal/<name>` (a send node's) is published on the topic; `from_ros`: every
    message on the topic becomes an occurrence (an accept node takes it). The payload is the
    value of `field`, or an object whose keys `fields` maps to field paths (`{path: key}`), or
    null for neither."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    direction: Literal["to_ros", "from_ros"]
    topic: str = Field(pattern=TOPIC)
    type: str
    field: str | None = None
    fields: dict[str, str] = Field(default_factory=dict)
    reliable: bool = True

    @model_validator(mode="after")
    def _check(self) -> SignalMap:
        types = _types()
        types.check_message(self.type)
        if self.field is not None and self.fields:
            raise ValueError("give 'field' (a value payload) or 'fields' (an object payload), not both")
        for path in ([self.field] if self.field is not None else list(self.fields)):
            types.scalar_field(self.type, path)
        return self


class Ros2Settings(BaseModel):
    """The settings of every ROS 2 component (the `ros2` service kind's driver `dds`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    domain_id: int | None = Field(default=None, ge=0, le=232,
                                  description="the ROS 2 domain (default: $ROS_DOMAIN_ID, else 0)")
    msg_paths: list[str] = Field(default_factory=list,
                                 description="folders of <package>/msg/*.msg and <package>/srv/*.srv")
    # the presets' settings
    topic: str | None = Field(default=None, pattern=TOPIC, description="ros2_range, ros2_twist")
    service: str | None = Field(default=None, pattern=TOPIC, description="ros2_setbool, ros2_trigger")
    stale_s: float = Field(default=1.0, gt=0, description="ros2_range: older readings are stale")
    first_s: float = Field(default=2.0, ge=0, description="ros2_range: wait for a first reading")
    timeout_s: float = Field(default=2.0, gt=0, le=60, description="service calls")
    # the generic implementation's
    features: dict[str, FeatureMap] = Field(default_factory=dict)
    # any ROS 2 component's
    signals: dict[str, SignalMap] = Field(default_factory=dict,
                                          description="signals of the model carried on ROS 2 topics")

    @model_validator(mode="after")
    def _extra_installed(self) -> Ros2Settings:
        _types()  # the definitions load (rosbags installed, msg_paths readable) or say why not
        return self

    @model_validator(mode="before")
    @classmethod
    def _paths_first(cls, data: Any) -> Any:
        paths = data.get("msg_paths", []) if isinstance(data, dict) else []
        _context.msg_paths = tuple(paths) if isinstance(paths, list) and all(
            isinstance(p, str) for p in paths) else ()
        return data


# ---------------------------------------------------------------------------------------------
# the presets


def preset(impl_id: str, settings: Ros2Settings) -> dict[str, FeatureMap]:
    """The features of a component: the preset's for `ros2_range`, `ros2_twist`,
    `ros2_setbool`, `ros2_trigger`; `settings.features` for `ros2`."""
    _context.msg_paths = tuple(settings.msg_paths)
    if impl_id == "ros2_range":
        return {"value": FeatureMap(returns="int", doc="latest range in cm", read=TopicRead(
            topic=settings.topic or "/range", type="sensor_msgs/msg/Range", field="range", scale=100.0,
            stale_s=settings.stale_s, first_s=settings.first_s))}
    if impl_id == "ros2_twist":
        topic = settings.topic or "/cmd_vel"
        return {
            "drive": FeatureMap(
                params=[ParamDecl(name="linear_mps", type="float", min=-5, max=5, unit="m/s"),
                        ParamDecl(name="angular_rps", type="float", min=-10, max=10, unit="rad/s")],
                doc="publish a Twist: linear.x, angular.z",
                publish=TopicWrite(topic=topic, type="geometry_msgs/msg/Twist",
                                   fields={"linear.x": "linear_mps", "angular.z": "angular_rps"})),
            "stop": FeatureMap(doc="publish a zero Twist",
                               publish=TopicWrite(topic=topic, type="geometry_msgs/msg/Twist")),
        }
    if impl_id in ("ros2_setbool", "ros2_trigger"):
        if settings.service is None:
            raise ValueError(f"{impl_id} needs 'service' (the ROS 2 service name)")
        if impl_id == "ros2_setbool":
            return {"set": FeatureMap(
                params=[ParamDecl(name="data", type="bool")], returns="bool", doc="SetBool; its success",
                call=ServiceCall(service=settings.service, type="std_srvs/srv/SetBool",
                                 fields={"data": "data"}, reply="success", timeout_s=settings.timeout_s))}
        return {"trigger": FeatureMap(returns="bool", doc="Trigger; its success", call=ServiceCall(
            service=settings.service, type="std_srvs/srv/Trigger", reply="success",
            timeout_s=settings.timeout_s))}
    if not settings.features and not settings.signals:
        raise ValueError("the generic ros2 implementation needs 'features' or 'signals'")
    return dict(settings.features)


def feature_specs(impl: Implementation, settings: dict[str, Any]) -> dict[str, FeatureSpec]:
    """The features a ROS 2 component offers with these deployment settings (`umlbot check`'s
    view); its static ones when the settings are not valid (their own errors say why)."""
    try:
        maps = preset(impl.id, Ros2Settings.model_validate(_without_prefixed(settings)))
    except Exception:
        return dict(impl.features)
    return {name: fmap.spec(name) for name, fmap in sorted(maps.items())}


def _without_prefixed(settings: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in settings.items() if not k.startswith(("mock_", "sim_"))}


def scaled(value: Any, scale: float, returns: ValueType) -> Any:
    """A field's value as the feature returns it (numbers scaled, `int` rounded)."""
    if isinstance(value, (bool, str)):
        return value
    value = value * scale
    if returns == "int":
        if not math.isfinite(value):
            raise ValueError(f"value {value} is not finite")
        return round(value)
    return value


Action = Literal["read", "publish", "call"]


def effective_domain(domain_id: int | None) -> int:
    """The ROS 2 domain: the setting, else `ROS_DOMAIN_ID` from the environment, else 0."""
    if domain_id is not None:
        return domain_id
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or not 0 <= int(text) <= 232:
        raise ValueError(f"ROS_DOMAIN_ID must be 0..232, got {text!r}")
    return int(text)
