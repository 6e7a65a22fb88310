"""umlbot: build a robot from UML models.

The package holds the command line (`umlbot.cli`), the error hierarchy (`umlbot.base.errors`), logging
(`umlbot.base.logs`), the shared clock (`umlbot.base.clock`) and the simulator (`umlbot.sim`). The model
compiler lives in the top-level package `compiler`, the MQTT bus, the hardware services and the
orchestrator in `services`.
"""

from umlbot.base.errors import ModelError, UmlbotError

__version__ = "0.1.0"

__all__ = ["ModelError", "UmlbotError", "__version__"]
