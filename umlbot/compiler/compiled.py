"""The compiled model: everything the orchestrator needs to run a robot, without the source files.

`umlbot compile` writes it with `write_compiled` (atomically: a reader never sees half a file) as
the bytes of `dump_compiled` (deterministic JSON: same model, same bytes; no timestamps); the
orchestrator reads it with `load_compiled`, which refuses a file written by a newer format version
with a clear message (an older one too: compile the model again). Graphs are resolved (every edge
names an existing node id), expressions are parsed trees (`umlbot.compiler.expr`), every name is
lane-resolved, and every component carries its implementation, service, driver and settings from
the deployment, and its implementation's safe stop from the library (so the orchestrator needs no
plugin installed).
"""

from __future__ import annotations

import gc
import json
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from umlbot.base.errors import CompiledModelError, ConfigError, ModelError
from umlbot.base.files import decode_utf8, write_atomically
from umlbot.base.library import ComponentKind, ServiceKind, StopArg
from umlbot.compiler.expr import Call, Expr

#: The version of the compiled file's shape; bumped on any incompatible change. 2: components
#: carry their safe stops (`CompiledComponent.safe_stop`).
FORMAT_VERSION = 2


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SafeStopCall(_Frozen):
    """One call that puts a component into its safe, stopped state (an L298N: `enabled(false)`)."""

    feature: str
    args: list[StopArg] = Field(default_factory=list)


class CompiledComponent(_Frozen):
    """A component bound to its implementation (canonical id) by the deployment."""

    kind: ComponentKind
    impl: str
    service: ServiceKind
    driver: str
    settings: dict[str, Any] = Field(default_factory=dict)
    #: the features the implementation offers (sorted).
    features: list[str] = Field(default_factory=list)
    #: the component diagram's ports: port name -> feature name.
    ports: dict[str, str] = Field(default_factory=dict)
    #: the implementation's safe-stop calls, which the orchestrator makes at start and end; taken
    #: from the library at compile time, so the robot needs no plugin where the orchestrator runs.
    safe_stop: list[SafeStopCall] = Field(default_factory=list)


class Link(_Frozen):
    """A link between two ports of the component diagram (informational: relations of data)."""

    id: str
    source_component: str
    source_port: str
    target_component: str
    target_port: str


# --- activity nodes -------------------------------------------------------------------------------


class _NodeBase(_Frozen):
    id: str
    #: 1-based line of the node in its lane's file (for traces and error messages).
    line: int = 0
    #: the node as the modeller wrote it (e.g. "LeftActuator.enabled(true)"), for traces and pictures.
    label: str = ""


class StartNode(_NodeBase):
    """The swimlane's entry point."""

    kind: Literal["start"] = "start"
    next: str


class EndNode(_NodeBase):
    """Ends the swimlane run (a virtual lane returns to its caller)."""

    kind: Literal["end"] = "end"


class ActionNode(_NodeBase):
    """Calls a component feature, a virtual swimlane or a builtin; the value is discarded."""

    kind: Literal["action"] = "action"
    call: Call
    next: str


class DatastoreNode(_NodeBase):
    """Evaluates `value` and stores it in the lane's datastore `name`."""

    kind: Literal["datastore"] = "datastore"
    name: str
    value: Expr
    next: str


class Branch(_Frozen):
    """One output of a decision; `guard` None is the `else` output."""

    guard: Expr | None = None
    target: str
    line: int = 0
    label: str = ""


class DecisionNode(_NodeBase):
    """Follows the first branch whose guard holds, else the `else` branch (always last, if any);
    when none holds and there is no `else`, this flow stops."""

    kind: Literal["decision"] = "decision"
    branches: list[Branch]


class ForkNode(_NodeBase):
    """Starts every target concurrently; `join` is the matching join that waits for all of them."""

    kind: Literal["fork"] = "fork"
    targets: list[str]
    join: str


class JoinNode(_NodeBase):
    """Waits until a flow arrived from each node in `incoming`, then continues once with `next`."""

    kind: Literal["join"] = "join"
    next: str
    incoming: list[str]


class SendNode(_NodeBase):
    """Publishes signal `signal` with the value of `payload` (None when absent)."""

    kind: Literal["send"] = "send"
    signal: str
    payload: Expr | None = None
    next: str


class AcceptNode(_NodeBase):
    """Waits for signal `signal`; stores its payload in datastore `store` when given."""

    kind: Literal["accept"] = "accept"
    signal: str
    store: str | None = None
    next: str


Node = Annotated[
    StartNode | EndNode | ActionNode | DatastoreNode | DecisionNode | ForkNode | JoinNode | SendNode
    | AcceptNode,
    Field(discriminator="kind"),
]


class Lane(_Frozen):
    """A swimlane: a component's lane (starts at start-up) or a virtual lane (runs when called)."""

    name: str
    virtual: bool
    component: str | None = None
    start: str
    nodes: dict[str, Node]
    #: the datastores this lane writes (sorted).
    datastores: list[str] = Field(default_factory=list)
    file: str = ""
    line: int = 0


class CompiledModel(_Frozen):
    """The whole compiled model."""

    format_version: int = FORMAT_VERSION
    #: the model's name; the default robot id (the deployment's `robot` wins when given).
    name: str
    source_hash: str
    #: time-out of one feature call, seconds.
    call_timeout_s: float = 2.0
    components: dict[str, CompiledComponent] = Field(default_factory=dict)
    links: list[Link] = Field(default_factory=list)
    signals: list[str] = Field(default_factory=list)
    lanes: dict[str, Lane] = Field(default_factory=dict)


def dump_compiled(model: CompiledModel) -> bytes:
    """The compiled file's bytes: compact JSON with sorted keys, UTF-8, one newline at the end;
    deterministic (same model, same bytes). `python -m json.tool FILE` shows it indented."""
    collecting = gc.isenabled()
    gc.disable()  # many short-lived dicts, no cycles: the collector would only slow this down
    try:
        data = model.model_dump(mode="json")
        # compact: with `indent` the json module falls back to its pure-Python encoder (5x slower)
        text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False,
                          allow_nan=False)
    finally:
        if collecting:
            gc.enable()
    return (text + "\n").encode("utf-8")


def write_compiled(model: CompiledModel, path: str | Path) -> None:
    """Write the compiled file at `path` (its folders made as needed) through a temporary file and
    a rename, so that a reader, e.g. a running orchestrator's restart, never sees half a file and a
    failed write keeps the previous file. `ConfigError` names the path when it cannot be written."""
    target = Path(path)
    try:
        write_atomically(target, dump_compiled(model))
    except OSError as exc:
        raise ConfigError(f"cannot write {target}: {exc.strerror or exc}") from exc


def load_compiled(source: str | Path | bytes) -> CompiledModel:
    """Read a compiled model from a path or from the file's bytes.

    Raises `CompiledModelError` when the file cannot be read, is corrupt, or was written by a newer
    format version than this umlbot understands.
    """
    where = "<bytes>"
    if isinstance(source, bytes):
        raw = source
    else:
        where = str(source)
        try:
            raw = Path(source).read_bytes()
        except OSError as exc:
            raise CompiledModelError(f"cannot read compiled model {where}: {exc.strerror}") from exc
    try:
        text = decode_utf8(raw, where)
    except ModelError as exc:
        raise CompiledModelError(f"{where}:{exc.line}:{exc.column}: not a compiled model "
                                 f"({exc.message})") from None
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise CompiledModelError(f"{where}: not a compiled model (not JSON: {exc})") from exc
    if not isinstance(data, dict) or "format_version" not in data:
        raise CompiledModelError(f"{where}: not a compiled model (no format_version)")
    version = data["format_version"]
    if not isinstance(version, int) or isinstance(version, bool):
        raise CompiledModelError(f"{where}: not a compiled model (format_version {version!r})")
    if version > FORMAT_VERSION:
        raise CompiledModelError(
            f"{where}: compiled model format version {version} is newer than this umlbot reads "
            f"(up to {FORMAT_VERSION}); upgrade umlbot or compile the model with this version"
        )
    if version < FORMAT_VERSION:  # it would lack what this version needs (the safe stops of 2)
        raise CompiledModelError(
            f"{where}: compiled model format version {version} was written by an older umlbot "
            f"(this one reads {FORMAT_VERSION}); compile the model again with this version"
        )
    try:
        return CompiledModel.model_validate(data)
    except RecursionError as exc:
        raise CompiledModelError(f"{where}: corrupt compiled model (nested too deeply)") from exc
    except ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise CompiledModelError(
            f"{where}: corrupt compiled model ({exc.error_count()} problem(s); first at {loc}: "
            f"{first['msg']})"
        ) from exc


__all__ = [
    "FORMAT_VERSION",
    "AcceptNode",
    "ActionNode",
    "Branch",
    "CompiledComponent",
    "CompiledModel",
    "DatastoreNode",
    "DecisionNode",
    "EndNode",
    "ForkNode",
    "JoinNode",
    "Lane",
    "Link",
    "Node",
    "SafeStopCall",
    "SendNode",
    "StartNode",
    "dump_compiled",
    "load_compiled",
    "write_compiled",
]
