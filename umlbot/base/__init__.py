"""The ground floor: what every other part of umlbot may import, and which imports nothing above it
(docs/architecture.md) — errors, files, the component library and its plugins, the deployment,
logs, clocks, YAML source positions, diagnostics, the driver registry, topic names."""

from umlbot.base.lazy import import_lean

# pydantic.types imports `secrets` (hmac, hashlib and OpenSSL's libcrypto: 3.3 MB resident) for
# SecretStr's comparison only; deferred, it loads on that first use (docs/performance.md, "Memory").
import_lean("pydantic.types", deferred=("secrets",))
