"""The robot's MQTT side: the shared bus (`services.bus`), the hardware services and the orchestrator."""
