"""umlbot: build a robot from UML models.

The package stacks in floors (docs/architecture.md): the ground floor `umlbot.base` (errors, files,
the component library, deployment, logs, clocks), the model compiler `umlbot.compiler`, the MQTT
bus, hardware services and orchestrator `umlbot.services`, and the applications on top (the sim,
the studio, the monitor and the command line `umlbot.cli`).
"""

from umlbot.base.errors import ModelError, UmlbotError

__version__ = "0.1.0"

__all__ = ["ModelError", "UmlbotError", "__version__"]
