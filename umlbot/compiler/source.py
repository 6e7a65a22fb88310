"""Reading a model's files: the component diagram, the swimlanes and the deployment, with positions.

A model is a folder (`model.yaml`, `activities/*.yaml`, `deployment.yaml` or `deployment.txt`)
or one YAML file holding everything. `load_source` reads it into `SourceModel` — plain data with a
`Location` on everything — and reports shape problems (unknown keys, wrong types) to the given
`Diagnostics`; the meaning is checked by `umlbot.compiler.checker`. See docs/model-format.md.
"""

from __future__ import annotations

import hashlib
import re
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from pydantic import ValidationError

from umlbot.base.catalog import component_kinds
from umlbot.base.deployment import Deployment, is_plain_format
from umlbot.base.diagnostics import Diagnostic, Diagnostics, Location
from umlbot.base.errors import ModelError
from umlbot.base.files import decode_utf8, file_problem, too_large
from umlbot.base.yamlsrc import YMap, YNode, YScalar, YSeq, locate, parse_yaml, to_python

MODEL_FILE = "model.yaml"
ACTIVITIES_DIR = "activities"
#: the relative path of an activity file (`activities/<name>.yaml` or `.yml`).
ACTIVITY_FILE = re.compile(rf"{ACTIVITIES_DIR}/[^/]+\.ya?ml")
DEPLOYMENT_FILES = ("deployment.yaml", "deployment.yml", "deployment.txt")

MODEL_KEYS = ("name", "call_timeout_s", "components", "links", "lanes", "deployment")
LANE_KEYS = ("lane", "nodes")
#: the parts of a model a file holds: what a file that could not be read leaves unknown.
Part = Literal["components", "lanes", "deployment", "name"]
#: model.yaml holds the component diagram (components and links), the model's name and may hold
#: swimlanes and the deployment; an activity file holds swimlanes; a deployment file, the deployment.
MODEL_FILE_PARTS: frozenset[Part] = frozenset(("components", "lanes", "deployment", "name"))
ACTIVITY_FILE_PARTS: frozenset[Part] = frozenset(("lanes",))
DEPLOYMENT_FILE_PARTS: frozenset[Part] = frozenset(("deployment",))
NODE_KINDS = ("start", "end", "action", "datastore", "decision", "fork", "join", "send", "accept")
#: the keys each node kind takes besides `id` and `kind`.
NODE_FIELDS: dict[str, tuple[str, ...]] = {
    "start": ("next",),
    "end": (),
    "action": ("call", "next"),
    "datastore": ("name", "value", "next"),
    "decision": ("branches",),
    "fork": ("targets",),
    "join": ("next",),
    "send": ("signal", "payload", "next"),
    "accept": ("signal", "store", "next"),
}


@dataclass
class SourceComponent:
    """A component of the component diagram; `ports` maps a port name to (feature, location)."""

    name: str
    loc: Location
    kind: str | None
    kind_loc: Location
    ports: dict[str, tuple[str, Location]] = field(default_factory=dict)


@dataclass
class LinkEnd:
    component: str
    port: str
    loc: Location


@dataclass
class SourceLink:
    id: str
    loc: Location
    source: LinkEnd | None
    target: LinkEnd | None


@dataclass
class SourceNode:
    """An activity node as written: its id, kind and the raw mapping of its fields."""

    id: str
    kind: str
    loc: Location
    fields: YMap
    id_loc: Location


@dataclass
class SourceLane:
    name: str
    loc: Location
    file: str  # path relative to the model root, as stored in the compiled file
    nodes: list[SourceNode] = field(default_factory=list)


@dataclass
class DeploymentEntry:
    """Where a component is named in the deployment, and where its implementation id is."""

    loc: Location
    impl_loc: Location


@dataclass
class SourceDeployment:
    deployment: Deployment | None
    file: str
    loc: Location
    entries: dict[str, DeploymentEntry] = field(default_factory=dict)
    #: False when a line of the plain format could not be read at all (its error is reported):
    #: which component it deployed is unknown, so none is reported as having no implementation.
    whole: bool = True
    #: components named on a line whose implementation could not be read (`Motor=`).
    unread: set[str] = field(default_factory=set)
    #: the rich format's mapping as written, to place a problem of a driver or its settings
    #: (None in the plain format, which has neither).
    root: YNode | None = None
    #: False when the file could not be read (its error is reported): what it deploys is unknown.
    read: bool = True


@dataclass(frozen=True)
class UnreadFile:
    """A model file that could not be read: its one error (reported) and the parts of a model it
    may have held. The checker leaves out every check that depends on those parts and says in
    that error how many it left out."""

    error: Diagnostic
    parts: frozenset[Part]


@dataclass
class Damage:
    """The parts of a model that were there but could not be read, or were of the wrong shape
    (see `SourceModel.damage`)."""

    #: the `components` section is not a mapping: any name may have been a component.
    all_components: bool = False
    #: components whose entry is damaged (a name that is not plain, no kind or an unreadable
    #: one): a reference to one is not reported again, its entry's error says what is wrong.
    components: set[str] = field(default_factory=set)
    #: components whose `ports` could not be read: a link to any port of one is not reported.
    ports: set[str] = field(default_factory=set)
    #: a `lanes` section, an activity file's top or a swimlane's name has the wrong shape: any
    #: name may have been a swimlane.
    all_lanes: bool = False
    #: swimlanes with a node or `nodes` of the wrong shape: their datastores and graph are not
    #: known whole (no "unknown datastore", "no start node", "goes to unknown node" for them).
    lanes: set[str] = field(default_factory=set)
    #: where the empty activity files are: their swimlanes may be what the model calls in vain.
    empty_files: list[Location] = field(default_factory=list)
    #: the files that could not be read (model.yaml, an activity file, the deployment file).
    unread: list[UnreadFile] = field(default_factory=list)

    def unread_holds(self, part: Part) -> bool:
        """Whether a file that could not be read may have held `part`."""
        return any(part in each.parts for each in self.unread)

    @property
    def components_unknown(self) -> bool:
        """Whether any name may have been a component (its `components` unread or not a mapping)."""
        return self.all_components or self.unread_holds("components")

    @property
    def lanes_unknown(self) -> bool:
        """Whether any name may have been a swimlane (a file that may hold swimlanes unread, or
        a swimlane's part of the wrong shape)."""
        return self.all_lanes or self.unread_holds("lanes")

    @property
    def calls_unknown(self) -> bool:
        """Whether a call of a virtual swimlane may have been in what could not be read (or which
        swimlanes are virtual is unknown): no "never called" warning then."""
        return self.components_unknown or self.lanes_unknown or bool(self.lanes)


@dataclass
class SourceModel:
    """Everything read from a model's files, positions included."""

    name: str
    loc: Location
    call_timeout_s: float = 2.0
    components: dict[str, SourceComponent] = field(default_factory=dict)
    links: list[SourceLink] = field(default_factory=list)
    lanes: list[SourceLane] = field(default_factory=list)
    deployment: SourceDeployment | None = None
    source_hash: str = ""
    #: What a file that could not be read or a section of the wrong shape leaves unknown (its
    #: error is reported, with its position). Its names are unknown rather than absent: the
    #: checker does not report a reference to one as missing, nor a virtual swimlane as never
    #: called when a call of it may have been in what could not be read; everything else is
    #: checked. See docs/model-format.md, "A file that cannot be read".
    damage: Damage = field(default_factory=Damage)


@dataclass(frozen=True)
class Unreadable:
    """A model file that is there but could not be read, in place of its bytes in `files`, and why
    (one line: "cannot read: Permission denied", "file too large (...)"). The reader reports it as
    it reports the file on disk: one error at `file:1:1`, and no follow-ons (`UnreadFile`)."""

    problem: str


def read_model_file(path: Path) -> bytes | Unreadable:
    """The bytes of one model file, or why they cannot be read (too large, an OS error)."""
    try:
        problem = file_problem(path.stat())
        if problem is not None:
            return Unreadable(problem)
        return path.read_bytes()  # grown meanwhile: `_Reader.read_text` measures it again
    except OSError as exc:
        return Unreadable(f"cannot read: {exc.strerror or exc}")


def _is_there(path: Path) -> bool:
    """Whether something has this model file's name: a file, or a folder, FIFO... under it, which
    is then reported as unreadable ("cannot read: Is a directory"), not as missing."""
    return path.exists() or path.is_symlink()


def _activity_paths(root: Path) -> list[Path]:
    """The activity files on disk (`activities/*.yaml`, `*.yml`), sorted; whatever has such a
    name, a folder too (reading it is its error)."""
    folder = root / ACTIVITIES_DIR
    if not folder.is_dir():
        return []
    return sorted([*folder.glob("*.yaml"), *folder.glob("*.yml")])


def read_model_folder(root: Path) -> dict[str, bytes | Unreadable]:
    """The files of the model folder `root` that `load_source` reads, by relative path, as it
    reads them: `load_source(root, files=read_model_folder(root))` reports what reading the folder
    reports, an unreadable file included. The deployment files are all there (the first one is
    read)."""
    if not root.is_dir():
        return {}
    candidates = [root / MODEL_FILE, *(root / name for name in DEPLOYMENT_FILES)]
    paths = [path for path in candidates if _is_there(path)] + _activity_paths(root)
    return {path.relative_to(root).as_posix(): read_model_file(path) for path in paths}


class _Reader:
    """Reads files of one model, remembering their bytes for the content hash.

    With `files` (relative path -> bytes, or `Unreadable`) the model's files are those, not the
    disk's: the studio checks its working copy this way, with the same messages and positions as
    on disk.
    """

    def __init__(self, root: Path, diagnostics: Diagnostics,
                 files: Mapping[str, bytes | Unreadable] | None = None,
                 cache: LaneCache | None = None) -> None:
        self.root = root
        self.diagnostics = diagnostics
        self.files = files
        self.cache = cache
        self.contents: dict[str, bytes] = {}
        #: the files that could not be read, in the order read.
        self.unread: list[UnreadFile] = []

    def could_not_read(self, exc: ModelError, parts: frozenset[Part]) -> None:
        """Report a file that could not be read (`exc` says why and where) and remember what it
        may have held."""
        self.unread.append(UnreadFile(self.diagnostics.add_model_error(exc), parts))

    def is_file(self, path: Path) -> bool:
        """Whether the model has a file at `path`: anything under that name (a folder named
        model.yaml is an unreadable model file, not a missing one)."""
        if self.files is None:
            return _is_there(path)
        return self.relative(path) in self.files

    def activity_files(self) -> list[Path]:
        """The activity files (`activities/*.yaml`, `*.yml`), sorted."""
        if self.files is None:
            return _activity_paths(self.root)
        folder = self.root / ACTIVITIES_DIR
        return sorted(folder / rel.split("/", 1)[1] for rel in self.files
                      if ACTIVITY_FILE.fullmatch(rel))

    def display(self, path: Path) -> str:
        return str(path)

    def relative(self, path: Path) -> str:
        try:
            return path.relative_to(self.root).as_posix()
        except ValueError:
            return path.name

    def read_text(self, path: Path) -> str:
        shown = self.display(path)
        if self.files is None:
            data = read_model_file(path)
        else:
            given = self.files.get(self.relative(path))
            data = Unreadable("cannot read: No such file or directory") if given is None else given
        if isinstance(data, bytes):
            problem = too_large(len(data))
            if problem is not None:
                data = Unreadable(problem)
        if isinstance(data, Unreadable):
            raise ModelError(data.problem, shown, 1, 1)
        self.contents[self.relative(path)] = data
        return decode_utf8(data, shown)

    def source_hash(self) -> str:
        digest = hashlib.sha256()
        for rel in sorted(self.contents):
            data = self.contents[rel]
            digest.update(f"{rel}\0{len(data)}\0".encode())
            digest.update(data)
        return "sha256:" + digest.hexdigest()


def load_source(path: str | Path, diagnostics: Diagnostics,
                deployment_path: str | Path | None = None,
                files: Mapping[str, bytes | Unreadable] | None = None,
                cache: LaneCache | None = None) -> SourceModel:
    """Read a model folder or a one-file model; shape problems go to `diagnostics`.

    `files` (path relative to the folder -> content, or `Unreadable` for a file that is there but
    could not be read: `read_model_folder`) replaces the folder's files on disk: the model is read
    from them, and positions and messages name the files as if they were on disk.
    Raises `ModelError` only when nothing sensible can be read (missing folder, no model.yaml).
    `cache` (kept by the caller from one read to the next, as the studio does) reuses what the
    swimlanes of an activity file whose text did not change read to: the same `SourceLane`s.
    """
    p = Path(path)
    if files is None and p.name == MODEL_FILE and p.is_file():
        # `model.yaml` of a folder model is the folder: its swimlanes and deployment are beside it
        p = p.parent
    if files is not None or p.is_dir():
        reader = _Reader(p, diagnostics, files, cache)
        model_file = p / MODEL_FILE
        if not reader.is_file(model_file):
            raise ModelError(f"not a model: no {MODEL_FILE} in this folder", str(p), 1, 1)
        model = _read_model_file_safe(reader, model_file, default_name=p.resolve().name)
        for lane_file in reader.activity_files():
            _read_lane_file(reader, lane_file, model)
        if deployment_path is None and model.deployment is None:
            for name in DEPLOYMENT_FILES:
                if reader.is_file(p / name):
                    deployment_path = p / name
                    break
    elif p.is_file():
        reader = _Reader(p.parent, diagnostics)
        model = _read_model_file_safe(reader, p, default_name=p.stem)
    else:
        raise ModelError("no such model folder or file", str(p), 1, 1)
    if deployment_path is not None:
        model.deployment = _read_deployment_file(reader, Path(deployment_path))
    model.source_hash = reader.source_hash()
    model.damage.unread = reader.unread
    return model


def _read_model_file_safe(reader: _Reader, path: Path, default_name: str) -> SourceModel:
    """Read the model file; when it is unreadable, report that and go on with an empty model."""
    try:
        return _read_model_file(reader, path, default_name)
    except ModelError as exc:
        reader.could_not_read(exc, MODEL_FILE_PARTS)
        return SourceModel(name=default_name, loc=Location(reader.display(path), 1, 1))


def _parse(reader: _Reader, path: Path) -> tuple[YNode | None, str]:
    shown = reader.display(path)
    text = reader.read_text(path)
    return parse_yaml(text, shown, reader.diagnostics), shown


def _read_model_file(reader: _Reader, path: Path, default_name: str) -> SourceModel:
    root, shown = _parse(reader, path)
    model = SourceModel(name=default_name, loc=Location(shown, 1, 1))
    if root is None:
        return model
    if not isinstance(root, YMap):
        raise ModelError("a model file is a mapping with 'components' and 'lanes'", shown,
                         root.loc.line, root.loc.column)
    if root.get("format_version") is not None:
        raise ModelError("this is a compiled model file (`umlbot run` runs it); "
                         "give the model's folder or its model.yaml", shown, 1, 1)
    d = reader.diagnostics
    _unknown_keys(root, MODEL_KEYS, "model", d)
    name = root.get("name")
    if name is not None:
        if isinstance(name, YScalar) and _is_identifier(name.text, allow_dash=True):
            model.name = name.text
        else:
            d.error("the model's name must be a plain name (letters, digits, _ and -)", name.loc)
    timeout = root.get("call_timeout_s")
    if timeout is not None:
        value = timeout.value if isinstance(timeout, YScalar) else None
        if isinstance(value, int | float) and not isinstance(value, bool) and 0 < value <= 3600:
            model.call_timeout_s = float(value)
        else:
            d.error("call_timeout_s must be a number of seconds, more than 0 and at most 3600",
                    timeout.loc)
    components = root.get("components")
    if components is not None:
        _read_components(components, model, d)
    links = root.get("links")
    if links is not None:
        _read_links(links, model, d)
    lanes = root.get("lanes")
    if lanes is not None:
        _read_lanes(lanes, reader.relative(path), model, d)
    deployment = root.get("deployment")
    if deployment is not None:
        model.deployment = _deployment_from_yaml(deployment, shown, d)
    return model


def _read_lane_file(reader: _Reader, path: Path, model: SourceModel) -> None:
    if reader.cache is not None:
        try:
            text = reader.read_text(path)
        except ModelError as exc:
            reader.could_not_read(exc, ACTIVITY_FILE_PARTS)
            return
        if reader.cache.read(text, reader.display(path), reader.relative(path), model,
                             reader.diagnostics):
            return
        reader.contents.pop(reader.relative(path), None)  # read again below, as without a cache
    try:
        root, shown = _parse(reader, path)
    except ModelError as exc:
        # Its swimlanes are unknown: every call of them would be a follow-on "unknown swimlane".
        reader.could_not_read(exc, ACTIVITY_FILE_PARTS)
        return
    _lanes_of(root, shown, reader.relative(path), model, reader.diagnostics)


def _lanes_of(root: YNode | None, shown: str, rel: str, model: SourceModel, d: Diagnostics) -> None:
    """Read the swimlanes of an activity file (`root`, None when empty) into `model`."""
    if root is None:
        # a warning, unless the model calls swimlanes defined nowhere: then the checker makes it
        # the one error that explains them (`check_source`)
        model.damage.empty_files.append(Location(shown, 1, 1))
        return
    if isinstance(root, YMap) and "lanes" in root.items:
        _unknown_keys(root, ("lanes",), "activity file", d)
        _read_lanes(root.items["lanes"], rel, model, d)
    else:
        _read_lane(root, rel, model, d)


def _read_components(node: YNode, model: SourceModel, d: Diagnostics) -> None:
    if not isinstance(node, YMap):
        d.error("'components' is a mapping: ComponentName: {kind: ..., ports: {...}}", node.loc)
        model.damage.all_components = True
        return
    for name in node:
        value = node.items[name]
        key_loc = node.key_loc(name)
        if not _is_identifier(name):
            d.error(f"component name {name!r} is not a plain name (letters, digits and _)", key_loc)
            model.damage.components.add(name)
            continue
        comp = SourceComponent(name=name, loc=key_loc, kind=None, kind_loc=key_loc)
        if isinstance(value, YScalar):
            comp.kind, comp.kind_loc = value.text, value.loc
        elif isinstance(value, YMap):
            _unknown_keys(value, ("kind", "ports"), f"component {name!r}", d)
            kind = value.get("kind")
            if isinstance(kind, YScalar):
                comp.kind, comp.kind_loc = kind.text, kind.loc
            elif kind is not None:
                d.error(f"a component's kind is one of {', '.join(component_kinds())}", kind.loc)
            else:
                d.error(f"component {name!r} has no kind ({', '.join(component_kinds())})", key_loc)
            ports = value.get("ports")
            if isinstance(ports, YMap):
                for port in ports:
                    feature = ports.items[port]
                    if not _is_identifier(port):
                        d.error(f"port name {port!r} is not a plain name", ports.key_loc(port))
                        model.damage.ports.add(name)
                    elif isinstance(feature, YScalar):
                        comp.ports[port] = (feature.text, feature.loc)
                    else:
                        d.error("a port names one feature of its component", feature.loc)
                        model.damage.ports.add(name)
            elif ports is not None:
                d.error("'ports' is a mapping: port_name: feature", ports.loc)
                model.damage.ports.add(name)
        else:
            d.error(f"component {name!r}: expected a kind or a mapping with 'kind'", value.loc)
        if comp.kind is None:
            model.damage.components.add(name)
            model.damage.ports.add(name)
        model.components[name] = comp


def _link_end(node: YNode | None, what: str, where: Location, d: Diagnostics) -> LinkEnd | None:
    if node is None:
        d.error(f"link has no '{what}' (Component.port)", where)
        return None
    if not isinstance(node, YScalar) or not re.fullmatch(r"[A-Za-z_]\w*\.[A-Za-z_]\w*", node.text):
        d.error(f"link '{what}' must be Component.port", node.loc)
        return None
    component, port = node.text.split(".")
    return LinkEnd(component, port, node.loc)


def _read_links(node: YNode, model: SourceModel, d: Diagnostics) -> None:
    if not isinstance(node, YSeq):
        d.error("'links' is a list of {from: Component.port, to: Component.port}", node.loc)
        return
    for index, item in enumerate(node.items, start=1):
        if not isinstance(item, YMap):
            d.error("a link is a mapping {from: Component.port, to: Component.port}", item.loc)
            continue
        _unknown_keys(item, ("id", "from", "to"), "link", d)
        ident = item.get("id")
        link_id = ident.text if isinstance(ident, YScalar) else f"link{index}"
        model.links.append(SourceLink(
            id=link_id, loc=item.loc,
            source=_link_end(item.get("from"), "from", item.loc, d),
            target=_link_end(item.get("to"), "to", item.loc, d),
        ))


def _read_lanes(node: YNode, rel: str, model: SourceModel, d: Diagnostics) -> None:
    if not isinstance(node, YSeq):
        d.error("'lanes' is a list of swimlanes, each {lane: Name, nodes: [...]}", node.loc)
        model.damage.all_lanes = True
        return
    for item in node.items:
        _read_lane(item, rel, model, d)


def _read_lane(node: YNode, rel: str, model: SourceModel, d: Diagnostics) -> None:
    if not isinstance(node, YMap):
        d.error("a swimlane is a mapping {lane: Name, nodes: [...]}", node.loc)
        model.damage.all_lanes = True
        return
    _unknown_keys(node, LANE_KEYS, "swimlane", d)
    name_node = node.get("lane")
    if not isinstance(name_node, YScalar) or not _is_identifier(name_node.text):
        where = name_node.loc if name_node is not None else node.loc
        d.error("a swimlane needs 'lane: Name' (a plain name)", where)
        model.damage.all_lanes = True
        return
    lane = SourceLane(name=name_node.text, loc=name_node.loc, file=rel)
    nodes = node.get("nodes")
    if nodes is None:
        d.error(f"swimlane {lane.name!r} has no 'nodes'", node.loc)
        model.damage.lanes.add(lane.name)
    elif not isinstance(nodes, YSeq):
        d.error("'nodes' is a list of activity nodes", nodes.loc)
        model.damage.lanes.add(lane.name)
    else:
        for item in nodes.items:
            source_node = _read_node(item, d)
            if source_node is not None:
                lane.nodes.append(source_node)
            else:
                model.damage.lanes.add(lane.name)
    model.lanes.append(lane)


def _read_node(node: YNode, d: Diagnostics) -> SourceNode | None:
    if not isinstance(node, YMap):
        d.error("an activity node is a mapping {id: ..., kind: ..., ...}", node.loc)
        return None
    ident = node.get("id")
    kind = node.get("kind")
    if not isinstance(ident, YScalar) or not _is_identifier(ident.text, allow_dash=True):
        where = ident.loc if ident is not None else node.loc
        d.error("an activity node needs 'id' (a plain name: letters, digits, _ and -)", where)
        return None
    if not isinstance(kind, YScalar) or kind.text not in NODE_KINDS:
        where = kind.loc if kind is not None else node.loc
        d.error(f"node {ident.text!r}: 'kind' must be one of {', '.join(NODE_KINDS)}", where)
        return None
    _unknown_keys(node, ("id", "kind", *NODE_FIELDS[kind.text]), f"{kind.text} node", d)
    return SourceNode(id=ident.text, kind=kind.text, loc=node.loc, fields=node, id_loc=ident.loc)


# --- reading again what did not change (the studio's edits) --------------------------------------

#: an activity file `lanes:` followed by its swimlanes, each starting with `- ` at one indent.
_LANES_HEADER = re.compile(r"lanes:[ \t]*(#.*)?")
_ITEM = re.compile(r"( *)- ")
#: what may make a swimlane's text mean something else alone than in its file: an anchor or an
#: alias (one may refer to another swimlane's), a tab, a directive or document marker
#: (`_not_alone`).
_ANCHOR = re.compile(r"&[^\s&]")
_ALIAS = re.compile(r"\*[^\s*]")
_MARKERS = ("---", "...", "%")


def _not_alone(text: str) -> bool:
    """Whether `text` may read otherwise in pieces than whole (`_pieces`)."""
    return ("\t" in text or text.startswith(_MARKERS) or any("\n" + m in text for m in _MARKERS)
            or _ANCHOR.search(text) is not None or _ALIAS.search(text) is not None)
#: a text this short cannot hold more YAML nodes than `umlbot.base.yamlsrc.MAX_NODES` (each takes
#: two characters or more), so that reading its swimlanes one by one refuses nothing more.
_ALONE_MAX_CHARS = 900_000


@dataclass
class _LaneRead:
    """What one swimlane's text read to: its `SourceLane`s, damage and shape problems."""

    lanes: list[SourceLane]
    damaged: set[str]
    all_lanes: bool
    problems: list[Diagnostic]
    empty_files: list[Location] = field(default_factory=list)

    @staticmethod
    def of(part: SourceModel, d: Diagnostics) -> _LaneRead:
        damage = part.damage
        return _LaneRead(part.lanes, damage.lanes, damage.all_lanes, d.items, damage.empty_files)


class LaneCache:
    """The swimlanes of activity files, read one by one and kept by their text and first line.

    An activity file of the form `lanes:` and a list of swimlanes is cut at each `- ` of the list,
    and each swimlane's text is read alone (YAML and shape), at its own lines; a text read before
    at the same place is not read again: its `SourceLane`s are the same objects as the last time
    (`umlbot.compiler.checker.CheckMemo` then reuses the checks of that swimlane). A file of
    another form, or whose pieces do not read alone exactly as the whole (an alias, a YAML error,
    a duplicate key), is read whole, as without a cache: the result is the same either way.
    """

    def __init__(self) -> None:
        self._entries: dict[tuple[str, str, int, str], _LaneRead] = {}
        self._used: dict[tuple[str, str, int, str], _LaneRead] = {}
        #: swimlane texts read again ("read") or not ("reused"), files read whole ("whole").
        self.stats: Counter[str] = Counter()

    def generation(self) -> None:
        """Forget what the last read did not use (called once per read of the model)."""
        self._entries, self._used = self._used, {}

    def read(self, text: str, shown: str, rel: str, model: SourceModel, d: Diagnostics) -> bool:
        """Read the swimlanes of one activity file's `text` into `model`; False (nothing done) when
        the file is not of the form read piece by piece."""
        pieces = _pieces(text)
        if pieces is None:
            # another form (one swimlane, ...): read whole, and not again while it is the same
            key = (shown, rel, -1, text)
            entry = self._used.get(key) or self._entries.get(key)
            if entry is None:
                entry = _read_whole(text, shown, rel)
                if entry is None:
                    return False
                self.stats["whole"] += 1
            else:
                self.stats["reused"] += 1
            self._used[key] = entry
            self._add(entry, model, d)
            return True
        reads: list[_LaneRead] = []
        for start, piece in pieces:
            key = (shown, rel, start, piece)
            entry = self._used.get(key) or self._entries.get(key)
            if entry is None:
                entry = _read_piece(piece, start, shown, rel)
                if entry is None:
                    return False
                self.stats["read"] += 1
            else:
                self.stats["reused"] += 1
            reads.append(entry)
            self._used[key] = entry
        for entry in reads:
            self._add(entry, model, d)
        return True

    @staticmethod
    def _add(entry: _LaneRead, model: SourceModel, d: Diagnostics) -> None:
        model.lanes.extend(entry.lanes)
        model.damage.lanes |= entry.damaged
        model.damage.all_lanes = model.damage.all_lanes or entry.all_lanes
        model.damage.empty_files.extend(entry.empty_files)
        d.items.extend(entry.problems)


def _pieces(text: str) -> list[tuple[int, str]] | None:
    """The swimlanes' texts of an activity file `lanes:` + a list, with the line (0-based) each
    starts at; None for a file of another form."""
    if len(text) > _ALONE_MAX_CHARS or _not_alone(text):
        return None
    lines = text.split("\n")
    index = 0
    while index < len(lines) and (not lines[index].strip() or lines[index].startswith("#")):
        index += 1
    if index == len(lines) or not _LANES_HEADER.fullmatch(lines[index]):
        return None
    pieces: list[tuple[int, str]] = []
    indent: str | None = None
    start = -1
    for number in range(index + 1, len(lines)):
        line = lines[number]
        content = line.lstrip(" ")
        if not content or content.startswith("#"):
            continue
        if indent is None:
            item = _ITEM.match(line)
            if item is None:
                return None
            indent = item.group(1)
        width = len(line) - len(content)
        if width < len(indent):
            return None  # another key of the file, or text at an indent the list does not have
        if width == len(indent):
            if not content.startswith("- "):
                return None
            if start >= 0:
                pieces.append((start, "\n".join(lines[start:number])))
            start = number
    if start < 0:
        return None
    pieces.append((start, "\n".join(lines[start:])))
    return pieces


def _read_piece(piece: str, start: int, shown: str, rel: str) -> _LaneRead | None:
    """One swimlane's text read alone at its lines; None when it does not read alone cleanly."""
    d = Diagnostics()
    try:
        # under a `lanes:` key of its own, as deep as in the file (`MAX_DEPTH` refuses the same)
        root = parse_yaml("\n" * (start - 1) + "lanes:\n" + piece, shown, d)
    except ModelError:
        return None
    if d.items or not isinstance(root, YMap) or len(root.items) != 1:
        return None
    lanes = root.items.get("lanes")
    if not isinstance(lanes, YSeq) or len(lanes.items) != 1:
        return None
    part = SourceModel(name="", loc=Location(shown, 1, 1))
    _read_lane(lanes.items[0], rel, part, d)
    return _LaneRead.of(part, d)


def _read_whole(text: str, shown: str, rel: str) -> _LaneRead | None:
    """An activity file read whole, as `_read_lane_file` reads it; None when it cannot be parsed
    (then it is read as without a cache, which reports that)."""
    d = Diagnostics()
    try:
        root = parse_yaml(text, shown, d)
    except ModelError:
        return None
    part = SourceModel(name="", loc=Location(shown, 1, 1))
    _lanes_of(root, shown, rel, part, d)
    return _LaneRead.of(part, d)


# --- deployment ------------------------------------------------------------------------------------


def _read_deployment_file(reader: _Reader, path: Path) -> SourceDeployment:
    shown = reader.display(path)
    # An unreadable or empty deployment file is its one error: a deployment without content (not
    # None, which the checker would report as a follow-on "the model has no deployment").
    try:
        text = reader.read_text(path)
        if is_plain_format(text):
            return _deployment_from_plain(text, shown, reader.diagnostics)
        root = parse_yaml(text, shown, reader.diagnostics)
    except ModelError as exc:
        reader.could_not_read(exc, DEPLOYMENT_FILE_PARTS)
        return SourceDeployment(None, shown, Location(shown, 1, 1), read=False)
    if root is None:
        reader.diagnostics.error("empty deployment", Location(shown, 1, 1))
        return SourceDeployment(None, shown, Location(shown, 1, 1))
    return _deployment_from_yaml(root, shown, reader.diagnostics)


def _deployment_from_plain(text: str, shown: str, d: Diagnostics) -> SourceDeployment:
    """The seed's `<component>=<implementation id>` lines, with a position for each."""
    from umlbot.base.deployment import ComponentDeployment

    result = SourceDeployment(None, shown, Location(shown, 1, 1))
    components: dict[str, ComponentDeployment] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        content = raw.split("#", 1)[0]
        if not content.strip():
            continue
        name, sep, impl = content.partition("=")
        column = len(name) - len(name.lstrip()) + 1
        loc = Location(shown, lineno, column)
        if not sep or not name.strip() or not impl.strip():
            d.error("expected '<component>=<implementation id>'", loc)
            if sep and name.strip():
                result.unread.add(name.strip())
            else:
                result.whole = False
            continue
        impl_column = len(name) + 2 + len(impl) - len(impl.lstrip())
        if name.strip() in components:
            d.error(f"component {name.strip()!r} deployed twice", loc)
            continue
        components[name.strip()] = ComponentDeployment(impl=impl.strip())
        result.entries[name.strip()] = DeploymentEntry(loc, Location(shown, lineno, impl_column))
    result.deployment = Deployment(components=components)
    return result


def _deployment_from_yaml(root: YNode, shown: str, d: Diagnostics) -> SourceDeployment:
    """The deployment in `root`; without content (`deployment` None) when it has problems."""
    if isinstance(root, YMap) and isinstance(root.get("deployment"), YMap):
        inner = root.get("deployment")
        assert inner is not None
        root = inner
    result = SourceDeployment(None, shown, root.loc, root=root)
    if not isinstance(root, YMap):
        d.error("a deployment is a mapping with 'components' (or the plain Component=impl lines)",
                root.loc)
        return result
    components = root.get("components")
    if isinstance(components, YMap):
        for name in components:
            entry = components.items[name]
            impl = entry.get("impl") if isinstance(entry, YMap) else None
            key_loc = components.key_loc(name)
            result.entries[name] = DeploymentEntry(key_loc, impl.loc if impl is not None else key_loc)
    try:
        result.deployment = Deployment.model_validate(to_python(root))
    except ValidationError as exc:
        for err in exc.errors():
            loc = locate(root, err["loc"])
            where = ".".join(str(p) for p in err["loc"])
            d.error(f"invalid deployment: {where}: {err['msg']}", loc)
    return result


# --- helpers ---------------------------------------------------------------------------------------

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_IDENT_DASH = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_\-]*")


def _is_identifier(text: str, allow_dash: bool = False) -> bool:
    return bool((_IDENT_DASH if allow_dash else _IDENT).fullmatch(text))


def _unknown_keys(node: YMap, allowed: tuple[str, ...], what: str, d: Diagnostics) -> None:
    for key in node:
        if key not in allowed:
            d.error(f"unknown key {key!r} in {what} (expected: {', '.join(allowed)})", node.key_loc(key))
