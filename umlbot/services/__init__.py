"""The robot's MQTT side: the shared bus (`umlbot.services.bus`), the hardware services and the
orchestrator."""
