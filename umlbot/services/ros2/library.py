"""The ROS 2 implementations, registered as umlbot's entry point `ros2` (umlbot.components):
light declarations only, no cyclonedds or rosbags (`umlbot.services.ros2.mapping` says what
their settings are)."""

from __future__ import annotations

from umlbot.base.library import (
    SENSOR,
    ComponentPlugin,
    FeatureSpec,
    Implementation,
    KindSpec,
    Param,
    ServiceSpec,
)

FEATURES_FROM = "umlbot.services.ros2.mapping:feature_specs"
SETTINGS_DOC = {
    "domain_id": "ROS_DOMAIN_ID (0)",
    "msg_paths": "folders of <package>/msg/*.msg and <package>/srv/*.srv",
    "topic": "the topic (ros2_range: /range, ros2_twist: /cmd_vel)",
    "service": "the ROS 2 service (ros2_setbool, ros2_trigger)",
    "stale_s": "ros2_range: a reading older than this is stale (1.0)",
    "first_s": "ros2_range: wait this long for a first reading (2.0)",
    "timeout_s": "service calls: wait this long for a reply (2.0)",
    "features": "ros2: each feature's read / publish / call (docs/ros2.md)",
    "signals": "signals of the model to or from ROS 2 topics (docs/ros2.md)",
}

#: A component that is a ROS 2 node: its features are named in the deployment.
ROS2_KIND = KindSpec("ros2", (), "a ROS 2 node: its features come from the deployment's mapping")

ROS2 = ComponentPlugin(
    kinds=(ROS2_KIND,),
    services=(ServiceSpec("ros2", "umlbot.services.ros2.service:Ros2Service",
                          "ROS 2 topics and services (DDS)", stop_when_orchestrator_offline=True),),
    implementations=(
        Implementation(id="ros2_range", kind="sensor", service="ros2", features=SENSOR.pick("value"),
                       title="ROS 2 range sensor (sensor_msgs/msg/Range)", features_from=FEATURES_FROM,
                       settings_doc=SETTINGS_DOC),
        Implementation(
            id="ros2_twist", kind="actuator", service="ros2",
            features={
                "drive": FeatureSpec("drive", (Param("linear_mps", "float", -5, 5, "m/s"),
                                               Param("angular_rps", "float", -10, 10, "rad/s")),
                                     "none", "publish a Twist: linear.x, angular.z"),
                "stop": FeatureSpec("stop", (), "none", "publish a zero Twist"),
            },
            title="ROS 2 base on /cmd_vel (geometry_msgs/msg/Twist)", features_from=FEATURES_FROM,
            safe_stop=(("stop", ()),), settings_doc=SETTINGS_DOC),
        Implementation(id="ros2_setbool", kind="ros2", service="ros2",
                       features={"set": FeatureSpec("set", (Param("data", "bool"),), "bool",
                                                    "std_srvs/srv/SetBool; its success")},
                       title="ROS 2 service std_srvs/srv/SetBool", features_from=FEATURES_FROM,
                       settings_doc=SETTINGS_DOC),
        Implementation(id="ros2_trigger", kind="ros2", service="ros2",
                       features={"trigger": FeatureSpec("trigger", (), "bool",
                                                        "std_srvs/srv/Trigger; its success")},
                       title="ROS 2 service std_srvs/srv/Trigger", features_from=FEATURES_FROM,
                       settings_doc=SETTINGS_DOC),
        Implementation(id="ros2", kind="ros2", service="ros2", features={},
                       title="ROS 2 topics and services named in the deployment",
                       features_from=FEATURES_FROM, settings_doc=SETTINGS_DOC),
    ),
)
