"""The ground floor: what every other part of umlbot may import, and which imports nothing above it
(docs/architecture.md) — errors, files, the component library and its plugins, the deployment,
logs, clocks, YAML source positions, diagnostics, the driver registry, topic names."""

import contextlib

from umlbot.base.entrypoints import select
from umlbot.base.lazy import import_lean

# pydantic.types imports `secrets` (hmac, hashlib and OpenSSL's libcrypto: 3.3 MB resident) for
# SecretStr's comparison only; deferred, it loads on that first use (docs/performance.md, "Memory").
import_lean("pydantic.types", deferred=("secrets",))

# pydantic looks for its plugins (`pydantic.plugin._loader`, imported at the first build of a model)
# with `from importlib.metadata import entry_points`, which imports email, zipfile, csv and
# tempfile: 1.7 MB of a service process. It gets umlbot's reader instead, which finds the same entry
# points (and hands over to importlib.metadata for a layout it does not read itself). A pydantic
# without that module looks for its plugins as it will.
with contextlib.suppress(ImportError):
    import_lean("pydantic.plugin._loader", provided={"importlib.metadata": {"entry_points": select}})
