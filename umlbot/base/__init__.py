"""The ground floor: what every other part of umlbot may import, and which imports nothing above it
(docs/architecture.md) — errors, files, the component library and its plugins, the deployment,
logs, clocks, YAML source positions, diagnostics, the driver registry, topic names."""
