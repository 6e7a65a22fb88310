"""The checks of a model and its translation into the compiled model.

`check_source` runs every check of SPEC §2 on a `SourceModel` (components and their kinds, the
deployment, each swimlane's graph, every expression's names and types, fork/join pairing,
recursion between virtual swimlanes), reports all problems to `Diagnostics` in one run, and
returns the `CompiledModel` when there is no error.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Literal, cast

from umlbot.base.catalog import component_features, component_kinds, kind_features, resolve_implementation
from umlbot.base.diagnostics import Diagnostic, Diagnostics, Location
from umlbot.base.errors import ConfigError, ModelError
from umlbot.base.library import ComponentKind, FeatureSpec, Implementation
from umlbot.base.yamlsrc import YMap, YScalar, YSeq, locate
from umlbot.compiler.compiled import CompiledModel, Lane
from umlbot.compiler.expr import BINARY_OPERATIONS
from umlbot.compiler.expr_parser import (
    RawExpr,
    RBinary,
    RCall,
    RConst,
    RName,
    RUnary,
    SourceText,
    parse_expression,
)
from umlbot.compiler.source import Damage, Part, SourceDeployment, SourceLane, SourceModel, SourceNode

#: expression types; "any" is a value whose type is known only at run time (a signal payload);
#: "unknown" exists only while datastore types are being inferred.
Type = Literal["int", "float", "bool", "str", "none", "any", "unknown"]

RESERVED = {"Application", "usleep", "msleep", "and", "or", "not", "true", "false", "True", "False",
            "null"}
SLEEP_BUILTINS = {"usleep": "us", "msleep": "ms"}
def _a(noun: str) -> str:
    """`noun` with its indefinite article: "a sensor", "an actuator"."""
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


NEXT_KINDS = ("start", "action", "datastore", "join", "send", "accept")
ARITHMETIC = ("+", "-", "*", "/", "%")
ORDERING = ("<", "<=", ">", ">=")


#: an expression tree as plain data in the shape of `umlbot.compiler.expr.Expr`; the whole compiled
#: model is built as data and validated once at the end (one fast pydantic call instead of one
#: per node: 10 000 nodes make about 50 000 objects).
Data = dict[str, Any]


def _const(value: object) -> Data:
    return {"op": "const", "value": value}


def _is_number_const(expr: Data) -> bool:
    value = expr.get("value")
    return expr["op"] == "const" and isinstance(value, int | float) and not isinstance(value, bool)


def _constant_number(expr: Data) -> int | float | None:
    """The value of an arithmetic expression of number constants (`90 * 3`, `-(10 + 5)`), computed
    as the orchestrator will; None when it reads anything else or cannot be computed (`1 / 0`)."""
    if _is_number_const(expr):
        return cast(int | float, expr["value"])
    if expr["op"] == "unary" and expr["operator"] == "-":
        operand = _constant_number(expr["operand"])
        return None if operand is None else -operand
    if expr["op"] == "binary" and expr["operator"] in ARITHMETIC:
        left, right = _constant_number(expr["left"]), _constant_number(expr["right"])
        if left is None or right is None:
            return None
        try:
            value = BINARY_OPERATIONS[expr["operator"]](left, right)
        except (ArithmeticError, ValueError):
            return None
        return value if isinstance(value, int | float) else None
    return None


def _skipped_plugins() -> str:
    """A hint for an unknown kind or implementation: the installed plugins that were skipped."""
    from umlbot.base.plugins import COMPONENTS_GROUP, catalog

    skipped = sorted({p.package.split(" ")[0] for p in catalog().problems if p.group == COMPONENTS_GROUP})
    return f"; skipped plugin packages: {', '.join(skipped)} (see 'umlbot plugins')" if skipped else ""


def _start(raw: RawExpr) -> int:
    """Where an expression's text begins (a binary's own offset is its operator's)."""
    while isinstance(raw, RBinary):
        raw = raw.left
    return raw.offset


def _call(target: Data, args: list[Data] | None = None) -> Data:
    return {"op": "call", "target": target, "args": args or []}


def _builtin(name: str, args: list[Data] | None = None) -> Data:
    return _call({"kind": "builtin", "name": name}, args)


def _type_of_const(value: object) -> Type:
    if value is None:
        return "any"  # `null`: what an unwritten datastore reads as
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "float"
    if isinstance(value, str):
        return "str"
    return "none"


def _numeric(t: Type) -> bool:
    return t in ("int", "float", "any", "unknown")


def _join(a: Type, b: Type) -> Type:
    """The type of a datastore written with values of types a and b."""
    if a == "unknown":
        return b
    if b == "unknown" or a == b:
        return a
    if {a, b} == {"int", "float"}:
        return "float"
    return "any"


def _describe(spec: FeatureSpec) -> str:
    return ", ".join(f"{p.name}: {p.type}" for p in spec.params)


@dataclass
class _Branch:
    guard: YScalar | None
    target: str | None
    target_loc: Location
    loc: Location
    is_else: bool


@dataclass
class _Node:
    """One activity node with its fields picked out of the YAML mapping."""

    src: SourceNode
    next: str | None = None
    next_loc: Location | None = None
    branches: list[_Branch] = field(default_factory=list)
    targets: list[tuple[str, Location]] = field(default_factory=list)
    #: decision outputs whose guard is missing or unreadable (reported): still flows, so that the
    #: node they lead to is not reported as having no path from the start as well.
    unguarded: list[tuple[str, Location]] = field(default_factory=list)
    expr: YScalar | None = None  # action call, datastore value or send payload
    name: str | None = None  # datastore name
    signal: str | None = None
    store: str | None = None
    compiled_expr: Data | None = None
    compiled_guards: list[Data | None] = field(default_factory=list)

    @property
    def id(self) -> str:
        return self.src.id

    def successors(self) -> list[str]:
        if self.src.kind == "decision":
            return [b.target for b in self.branches if b.target is not None] + [t for t, _ in self.unguarded]
        if self.src.kind == "fork":
            return [t for t, _ in self.targets]
        return [self.next] if self.next is not None else []


@dataclass
class _Lane:
    src: SourceLane
    virtual: bool
    nodes: dict[str, _Node] = field(default_factory=dict)
    order: list[str] = field(default_factory=list)
    start: str | None = None
    #: datastore name -> the value expressions written to it (None: an accept's payload).
    writes: dict[str, list[YScalar | None]] = field(default_factory=dict)
    fork_join: dict[str, str] = field(default_factory=dict)
    incoming: dict[str, list[str]] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.src.name


@dataclass
class _Scope:
    """What names mean in the whole model."""

    kinds: dict[str, ComponentKind] = field(default_factory=dict)
    impls: dict[str, Implementation] = field(default_factory=dict)
    lanes: dict[str, _Lane] = field(default_factory=dict)
    datastore_types: dict[tuple[str, str], Type] = field(default_factory=dict)
    #: what could not be read (`umlbot.compiler.source.Damage`): names that may have been there.
    damage: Damage = field(default_factory=Damage)
    #: components whose kind is unknown (a damaged entry, an unknown kind): their own error says so.
    unknown_components: set[str] = field(default_factory=set)
    #: any name may be a component (`Damage.components_unknown`); then which swimlanes are virtual
    #: is unknown too.
    components_unknown: bool = False
    #: any name may be a swimlane (`Damage.lanes_unknown`).
    lanes_unknown: bool = False
    #: the deployment file could not be read: feature calls are checked by their component's kind.
    deployment_unread: bool = False

    def may_be_component(self, name: str) -> bool:
        """Whether `name` may be a component whose entry could not be read whole."""
        return self.components_unknown or name in self.unknown_components

    def feature_spec(self, component: str, feature: str) -> FeatureSpec | None:
        impl = self.impls.get(component)
        if impl is not None and feature in impl.features:
            return impl.features[feature]
        return kind_features(self.kinds[component]).get(feature)


#: how many swimlanes defined nowhere an empty activity file's error names.
MAX_LISTED = 10


@dataclass
class _LaneCall:
    caller: str
    callee: str
    loc: Location


class _ExprChecker:
    """Resolves the names of one expression and computes its type; errors are `ModelError`s."""

    def __init__(self, scope: _Scope, lane: str, src: SourceText) -> None:
        self.scope = scope
        self.lane = lane
        self.src = src
        self.lane_calls: list[_LaneCall] = []
        #: whether a datastore was read (type inference needs another pass only then)
        self.read_datastore = False
        #: the checks left out (`unknown`), each with the parts of the model it depends on.
        self.left_out: list[tuple[Part, ...]] = []
        #: swimlanes named but defined nowhere while an activity file is empty, and where.
        self.missing: list[tuple[str, Location]] = []

    def fail(self, message: str, offset: int) -> ModelError:
        return self.src.error(message, offset)

    def unknown(self, *parts: Part, call: bool = False, args: list[Data] | None = None) -> tuple[Data, Type]:
        """A name that may be in what could not be read (`parts` of the model, none for a section
        of the wrong shape): not an error of its own (that part's error is reported), and the
        check is left out. The expression goes on with a value of any type, a call's (`call`) or a
        datastore's, so that its other names are still checked without follow-ons."""
        self.left_out.append(parts)
        return (_call({"kind": "unknown"}, args) if call else _const(None)), "any"

    def unknown_lane(self, name: str, offset: int, message: str, call: bool) -> tuple[Data, Type]:
        """A name of a swimlane that is not there: left out when it may be in what could not be
        read or in an empty activity file (collected for its one error), else an error."""
        if self.scope.lanes_unknown:
            return self.unknown("lanes", call=call)
        if self.scope.damage.empty_files:
            self.missing.append((name, self.src.location(offset)))
            return self.unknown(call=call)
        raise self.fail(message, offset)

    def resolve(self, raw: RawExpr, action: bool = False) -> tuple[Data, Type]:
        if isinstance(raw, RConst):
            return _const(raw.value), _type_of_const(raw.value)
        if isinstance(raw, RName):
            return self.resolve_name(raw, action)
        if isinstance(raw, RCall):
            return self.resolve_call(raw, action)
        if isinstance(raw, RUnary):
            operand, t = self.resolve(raw.operand)
            if raw.operator == "not":
                if t not in ("bool", "any", "unknown"):
                    raise self.fail(f"'not' needs a bool, got {t}", raw.offset)
                return {"op": "unary", "operator": "not", "operand": operand}, "bool"
            if not _numeric(t):
                raise self.fail(f"'-' needs a number, got {t}", raw.offset)
            if _is_number_const(operand):
                return _const(-operand["value"]), t
            return {"op": "unary", "operator": "-", "operand": operand}, t
        return self.resolve_binary(raw)

    def resolve_binary(self, raw: RBinary) -> tuple[Data, Type]:
        left, lt = self.resolve(raw.left)
        right, rt = self.resolve(raw.right)
        op = raw.operator
        expr = {"op": "binary", "operator": op, "left": left, "right": right}
        loose = ("any", "unknown")
        if "unknown" in (lt, rt) and op in ARITHMETIC:
            return expr, "unknown"
        if op in ("and", "or"):
            for t in (lt, rt):
                if t not in ("bool", *loose):
                    raise self.fail(f"'{op}' needs bools, got {lt} and {rt}", raw.offset)
            return expr, "bool"
        if op in ("==", "!="):
            for t in (lt, rt):
                if t == "none":
                    raise self.fail(f"'{op}' compares values, but one side gives no value", raw.offset)
            return expr, "bool"
        if op in ORDERING:
            if (_numeric(lt) and _numeric(rt)) or (lt in ("str", *loose) and rt in ("str", *loose)):
                return expr, "bool"
            raise self.fail(f"'{op}' needs two numbers or two strings, got {lt} and {rt}", raw.offset)
        if op == "+" and lt in ("str", *loose) and rt in ("str", *loose) and "str" in (lt, rt):
            return expr, "str"
        if not (_numeric(lt) and _numeric(rt)) or "bool" in (lt, rt):
            raise self.fail(f"'{op}' needs numbers, got {lt} and {rt}", raw.offset)
        if "any" in (lt, rt):
            return expr, "any"
        if op == "/":
            return expr, "float"
        return expr, "int" if lt == rt == "int" else "float"

    def datastore_type(self, lane: str, name: str) -> Type | None:
        return self.scope.datastore_types.get((lane, name))

    def resolve_name(self, raw: RName, action: bool) -> tuple[Data, Type]:
        scope = self.scope
        if len(raw.parts) == 1:
            name = raw.parts[0]
            t = self.datastore_type(self.lane, name)
            if t is not None:
                self.read_datastore = True
                return {"op": "ref", "lane": self.lane, "name": name}, t
            if name in scope.lanes and scope.lanes[name].virtual:
                return self.lane_call(name, raw.offset, action)
            if name in SLEEP_BUILTINS:
                raise self.fail(f"{name} needs an argument: {name}({SLEEP_BUILTINS[name]})", raw.offset)
            if name in scope.kinds:
                raise self.fail(f"'{name}' is a component; call one of its features: "
                                f"{name}.<feature>(...)", raw.offset)
            if action:
                return self.unknown_lane(name, raw.offset, f"unknown swimlane or builtin '{name}'", True)
            if self.lane in scope.damage.lanes:
                return self.unknown()
            raise self.fail(f"unknown datastore '{name}' in swimlane '{self.lane}'", raw.offset)
        owner, name = raw.parts
        if owner == "Application":
            if name == "exit":
                return _builtin("Application.exit"), "bool"
            raise self.fail(f"unknown builtin 'Application.{name}' (known: Application.exit)",
                            raw.offsets[1])
        if owner in scope.lanes or owner in scope.kinds:
            t = self.datastore_type(owner, name)
            if t is not None:
                self.read_datastore = True
                return {"op": "ref", "lane": owner, "name": name}, t
            if owner in scope.damage.lanes:
                return self.unknown()
            if owner not in scope.lanes and scope.lanes_unknown:
                return self.unknown("lanes")  # the component's swimlane may be in what is unread
            hint = ""
            if owner in scope.kinds and name in kind_features(scope.kinds[owner]):
                hint = f"; to call the feature, write {owner}.{name}()"
            raise self.fail(f"unknown datastore '{name}' in swimlane '{owner}'{hint}", raw.offsets[1])
        if scope.lanes_unknown:
            return self.unknown("lanes")  # a datastore of a swimlane that may be in what is unread
        if scope.may_be_component(owner):
            return self.unknown()
        return self.unknown_lane(owner, raw.offset, f"unknown swimlane or component '{owner}'", False)

    def lane_call(self, name: str, offset: int, action: bool) -> tuple[Data, Type]:
        if not action:
            raise self.fail(f"a call of swimlane '{name}' is an action of its own; it gives no value",
                            offset)
        if self.scope.components_unknown:
            # whether it is a virtual swimlane or a component's is the component diagram's to say
            self.unknown("components")
        self.lane_calls.append(_LaneCall(self.lane, name, self.src.location(offset)))
        return _call({"kind": "lane", "lane": name}), "none"

    def resolve_call(self, raw: RCall, action: bool) -> tuple[Data, Type]:
        scope = self.scope
        parts = raw.name.parts
        if len(parts) == 1:
            name = parts[0]
            if name in SLEEP_BUILTINS:
                if len(raw.args) != 1:
                    raise self.fail(f"{name} takes 1 argument ({SLEEP_BUILTINS[name]}), got "
                                    f"{len(raw.args)}", raw.offset)
                arg, t = self.resolve(raw.args[0])
                if not _numeric(t):
                    raise self.fail(f"{name} needs a number of {SLEEP_BUILTINS[name]}, got {t}",
                                    raw.args[0].offset)
                duration = _constant_number(arg)
                if duration is not None and duration < 0:
                    raise self.fail(f"{name} needs a duration of 0 or more, got {duration:g}",
                                    _start(raw.args[0]))
                return _builtin(name, [arg]), "none"
            if name in scope.lanes:
                if not scope.lanes[name].virtual:
                    raise self.fail(f"'{name}' is the swimlane of component '{name}'; only virtual "
                                    "swimlanes can be called", raw.offset)
                if raw.args:
                    raise self.fail(f"swimlane '{name}' takes no arguments, got {len(raw.args)}",
                                    raw.args[0].offset)
                return self.lane_call(name, raw.offset, action)
            if name in scope.kinds:
                raise self.fail(f"'{name}' is a component; call one of its features: "
                                f"{name}.<feature>(...)", raw.offset)
            return self.unknown_lane(name, raw.offset, f"unknown swimlane or builtin '{name}'", True)
        owner, feature = parts
        if owner == "Application":
            if feature == "exit" and not raw.args:
                return _builtin("Application.exit"), "bool"
            if feature == "exit":
                raise self.fail("Application.exit takes no arguments", raw.args[0].offset)
            raise self.fail(f"unknown builtin 'Application.{feature}' (known: Application.exit)",
                            raw.name.offsets[1])
        if owner not in scope.kinds:
            if scope.may_be_component(owner):
                # its arguments are checked all the same: they do not depend on the component
                return self.unknown(*(("components",) if scope.components_unknown else ()), call=True,
                                    args=[self.resolve(arg)[0] for arg in raw.args])
            if owner in scope.lanes:
                raise self.fail(f"'{owner}' is a virtual swimlane, not a component; call it as "
                                f"{owner}()", raw.offset)
            raise self.fail(f"unknown component '{owner}'", raw.offset)
        kind = scope.kinds[owner]
        impl = scope.impls.get(owner)
        if impl is None and scope.deployment_unread:
            self.unknown("deployment")  # the implementation's features and ranges; its kind's are checked
        if feature not in kind_features(kind) and (impl is None or feature not in impl.features):
            # the features this component offers: its implementation's, else its kind's
            known = ", ".join(impl.features if impl is not None else kind_features(kind))
            raise self.fail(f"unknown feature '{feature}' of {kind} component '{owner}' "
                            f"(known: {known})", raw.name.offsets[1])
        if impl is not None and feature not in impl.features:
            raise self.fail(f"implementation '{impl.id}' of '{owner}' does not offer feature "
                            f"'{feature}' (it offers: {', '.join(impl.features)})", raw.name.offsets[1])
        spec = scope.feature_spec(owner, feature)
        assert spec is not None
        if len(raw.args) != len(spec.params):
            raise self.fail(f"{owner}.{feature} takes {len(spec.params)} argument(s) "
                            f"({_describe(spec)}), got {len(raw.args)}", raw.offset)
        args: list[Data] = []
        for index, (raw_arg, param) in enumerate(zip(raw.args, spec.params, strict=True), start=1):
            arg, t = self.resolve(raw_arg)
            ok = (t in ("any", "unknown") or t == param.type
                  or (param.type == "float" and t == "int"))
            if not ok:
                raise self.fail(f"argument {index} ({param.name}) of {owner}.{feature} must be "
                                f"{param.type}, got {t}", raw_arg.offset)
            value = _constant_number(arg)
            if value is not None:
                low, high = param.minimum, param.maximum
                if (low is not None and value < low) or (high is not None and value > high):
                    by = f" by implementation '{impl.id}'" if impl is not None else ""
                    raise self.fail(f"argument {index} ({param.name}) of {owner}.{feature} must be "
                                    f"{low:g}..{high:g}{by}, got {value:g}", _start(raw_arg))
            args.append(arg)
        target = {"kind": "feature", "component": owner, "feature": feature}
        return _call(target, args), cast(Type, spec.returns)


@dataclass
class _LaneChecks:
    """What checking one swimlane found, kept for the next check (`CheckMemo`)."""

    src: SourceLane
    virtual: bool
    damaged: bool
    lane: _Lane
    #: its nodes' and graph's problems and signals: they depend on its text only.
    problems: list[Diagnostic]
    signals: set[str]
    #: the scope its expressions were checked in (`_Checker.scope_key`), and what they gave:
    #: problems, checks left out, swimlanes named in vain, calls of swimlanes (its nodes hold
    #: the compiled expressions).
    scope_key: tuple[Any, ...] | None = None
    expr_problems: list[Diagnostic] = field(default_factory=list)
    left_out: list[tuple[Part, ...]] = field(default_factory=list)
    missing: list[tuple[str, Location]] = field(default_factory=list)
    lane_calls: list[_LaneCall] = field(default_factory=list)
    #: its compiled swimlane, validated (`_Checker.build_lane`)
    built: Lane | None = None


class CheckMemo:
    """What the last check of a model found per swimlane, for the next check of the same model
    (the studio checks its working copy after every edit).

    A swimlane whose `SourceLane` is the same object as the last time (`LaneCache` gives it when
    its text did not change) is not read again, and its graph not checked again; its expressions
    are not checked again either when everything outside it that they can name is as before
    (components, their implementations, swimlanes, every datastore's type, what could not be
    read). The problems and the compiled model are those of a check from scratch.
    """

    MAX_TREES = 50_000

    def __init__(self) -> None:
        self.lanes: dict[int, _LaneChecks] = {}
        #: expression text -> its parsed tree (offsets are relative to the text)
        self.trees: dict[str, RawExpr] = {}
        #: a datastore's value that reads no datastore -> its type, in the scope of the key
        #: (`_Checker.names_key`): it is the same in every pass of the inference, and next time
        self.values: dict[int, tuple[YScalar, str, tuple[Any, ...], Type]] = {}
        self.names_key: tuple[Any, ...] = ()

    def get(self, src: SourceLane, virtual: bool, damaged: bool) -> _LaneChecks | None:
        entry = self.lanes.get(id(src))
        if entry is None or entry.src is not src or entry.virtual != virtual or entry.damaged != damaged:
            return None
        return entry


class _Checker:
    def __init__(self, source: SourceModel, diagnostics: Diagnostics,
                 memo: CheckMemo | None = None) -> None:
        self.source = source
        self.d = diagnostics
        self.memo = memo
        #: the swimlanes' entries of this check (which become `memo.lanes` after it)
        self.entries: dict[str, _LaneChecks] = {}
        #: while one swimlane's expressions are checked for the memo: what they leave out, miss
        self.recording: _LaneChecks | None = None
        damage = source.damage
        self.scope = _Scope(damage=damage, components_unknown=damage.components_unknown,
                            lanes_unknown=damage.lanes_unknown)
        self.lanes: list[_Lane] = []
        #: how many checks each file that could not be read left out (`leave_out`), by position
        #: in `damage.unread`.
        self.left_out = [0] * len(damage.unread)
        #: swimlanes called but defined nowhere while an activity file is empty -> first call.
        self.missing_lanes: dict[str, Location] = {}
        self.lane_calls: list[_LaneCall] = []
        self.signals: set[str] = set()
        #: the implementation of each component the deployment names, when it is known and of the
        #: component's kind (or the component's kind is unknown): its driver and settings are checked.
        self.deployed: dict[str, Implementation] = {}
        self.parsed: dict[int, tuple[RawExpr, SourceText]] = {}
        self.trees: dict[str, RawExpr] = {}
        if memo is not None:
            if len(memo.trees) > CheckMemo.MAX_TREES:
                memo.trees.clear()
            self.trees = memo.trees

    def leave_out(self, *parts: Part) -> None:
        """Count a check left out because it depends on `parts` of the model, for each file that
        could not be read and may hold one of them (a section of the wrong shape counts nowhere:
        its error says what is unknown)."""
        for index, each in enumerate(self.source.damage.unread):
            if not each.parts.isdisjoint(parts):
                self.left_out[index] += 1

    def report_left_out(self) -> None:
        """Say in the error of each file that could not be read how many checks were left out
        because of it."""
        for each, count in zip(self.source.damage.unread, self.left_out, strict=True):
            if count:
                checks = "1 check that depends on this file was" if count == 1 else \
                    f"{count} checks that depend on this file were"
                self.d.add_note(each.error, f"{checks} left out until it can be read")

    # --- components and deployment -----------------------------------------------------------------

    def check_components(self) -> None:
        for name, comp in self.source.components.items():
            if name in RESERVED:
                self.d.error(f"'{name}' is a reserved name; choose another component name", comp.loc)
                continue
            if comp.kind is None:
                self.scope.unknown_components.add(name)
                continue
            if comp.kind not in component_kinds():
                self.d.error(f"unknown component kind '{comp.kind}' (known: "
                             f"{', '.join(component_kinds())}){_skipped_plugins()}", comp.kind_loc)
                self.scope.unknown_components.add(name)
                continue
            kind: ComponentKind = comp.kind
            self.scope.kinds[name] = kind
            for port, (feature, loc) in comp.ports.items():
                if feature not in kind_features(kind) and not self._features_from_settings(name):
                    self.d.error(f"port '{port}' names unknown feature '{feature}' of {kind} component "
                                 f"'{name}' (known: {', '.join(kind_features(kind))})", loc)
        for link in self.source.links:
            for end in (link.source, link.target):
                if end is None:
                    continue
                comp_src = self.source.components.get(end.component)
                if comp_src is None:
                    if not self.scope.may_be_component(end.component):
                        self.d.error(f"link '{link.id}' names unknown component '{end.component}'",
                                     end.loc)
                elif end.port not in comp_src.ports and end.component not in self.source.damage.ports:
                    self.d.error(f"link '{link.id}' names unknown port '{end.port}' of component "
                                 f"'{end.component}'", end.loc)

    def _features_from_settings(self, name: str) -> bool:
        """Whether the component's implementation takes its features from the deployment's
        settings (a ROS 2 mapping): its ports are checked against them with the deployment."""
        dep = self.source.deployment
        entry = dep.deployment.components.get(name) if dep is not None and dep.deployment else None
        impl = resolve_implementation(entry.impl) if entry is not None else None
        return impl is not None and bool(impl.features_from)

    def check_deployment(self) -> None:
        dep = self.source.deployment
        if dep is None:
            # unless model.yaml, which may have a `deployment`, could not be read
            if not self.source.damage.unread_holds("deployment"):
                self.d.error("the model has no deployment (deployment.yaml or deployment.txt beside "
                             "model.yaml, or a 'deployment' section)", self.source.loc)
            return
        if dep.deployment is None:
            # its problems were reported while reading it; when it could not be read, the
            # activities are checked by the components' kinds instead of their implementations
            if not dep.read:
                self.scope.deployment_unread = True
                for _ in self.scope.kinds:
                    self.leave_out("deployment")  # its implementation, of its kind, offering its ports
            return
        self.check_robot_id(dep)
        for name, entry in dep.deployment.components.items():
            where = dep.entries.get(name)
            loc = where.loc if where else dep.loc
            impl_loc = where.impl_loc if where else dep.loc
            declared = name in self.source.components
            if not declared and not self.scope.may_be_component(name):
                self.d.error(f"deployment names unknown component '{name}'", loc)
                continue
            # a component whose entry could not be read: its implementation, driver and settings
            # are checked all the same (they do not depend on it), not its kind
            impl = resolve_implementation(entry.impl)
            if impl is None:
                self.d.error(f"unknown implementation id '{entry.impl}' for component '{name}'"
                             f"{_skipped_plugins()}", impl_loc)
                continue
            kind = self.scope.kinds.get(name)
            if kind is None:
                if not declared:
                    self.leave_out("components")  # whether it is a component, of the implementation's kind
            elif impl.kind != kind:
                self.d.error(f"component '{name}' is {_a(kind)} but implementation '{impl.id}' is "
                             f"{_a(impl.kind)}", impl_loc)
                continue
            else:
                impl = component_features(impl, entry.settings)
                self.scope.impls[name] = impl
                for port, (feature, port_loc) in self.source.components[name].ports.items():
                    mapped = feature in kind_features(kind) or impl.features_from
                    if mapped and feature not in impl.features:
                        self.d.error(f"implementation '{impl.id}' of '{name}' does not offer feature "
                                     f"'{feature}' (port '{port}')", port_loc)
            self.deployed[name] = impl
            if self.check_driver(name, impl, dep):
                self.check_settings(name, impl, dep)
        self.check_default_driver(dep)
        self.check_shared_pins(dep)
        if not dep.whole:
            return  # a line that could not be read may have deployed any of them
        for name, comp in self.source.components.items():
            if (name not in dep.deployment.components and name not in dep.unread
                    and comp.kind in component_kinds()):
                self.d.error(f"component '{name}' has no implementation in the deployment", comp.loc)

    def _deployment_loc(self, dep: SourceDeployment, *path: int | str) -> Location:
        """The position of `path` in the rich deployment (as deep as it is written)."""
        return locate(dep.root, path) if dep.root is not None else dep.loc

    def check_robot_id(self, dep: SourceDeployment) -> None:
        """The robot id (the deployment's `robot`, else the model's name) is one MQTT topic level:
        every topic of the robot is `umlbot/<robot>/…`."""
        from umlbot.base.topics import check_name

        assert dep.deployment is not None
        robot = dep.deployment.robot
        if robot is None and self.source.damage.unread_holds("name"):
            return  # the robot id is the model's name, in model.yaml, which could not be read
        try:
            check_name("robot id" if robot is not None else "the model's name", robot or self.source.name)
        except ConfigError as exc:
            if robot is not None:
                self.d.error(str(exc), self._deployment_loc(dep, "robot"))
            else:  # a folder's name: the model has no `name` of its own
                self.d.error(f"{exc}; it is the robot id: give the model a `name` (or the deployment "
                             "a `robot`)", self.source.loc)

    def check_driver(self, name: str, impl: Implementation, dep: SourceDeployment) -> bool:
        """The driver a component's service would start with exists (built-in or a plugin's). An
        unknown default driver is reported once (`check_default_driver`), not per component."""
        from umlbot.base.registry import known_drivers

        assert dep.deployment is not None
        own = dep.deployment.components[name].driver
        driver = dep.deployment.driver_for(name)
        known = known_drivers(impl.service)
        if driver in known:
            return True
        if own is not None:
            self.d.error(f"unknown driver '{driver}' for '{name}' ({impl.service} service; known: "
                         f"{', '.join(known)})", self._deployment_loc(dep, "components", name, "driver"))
        return False

    def check_default_driver(self, dep: SourceDeployment) -> None:
        """The deployment's `driver`, for every service it is the driver of: one error when no
        service has it (a misspelling), else one per service that lacks it."""
        from umlbot.base.registry import known_drivers

        assert dep.deployment is not None
        default = dep.deployment.driver
        by_service: dict[str, list[str]] = {}
        for name, entry in dep.deployment.components.items():
            impl = self.deployed.get(name)
            if impl is not None and entry.driver is None:
                by_service.setdefault(impl.service, []).append(name)
        known = {service: known_drivers(service) for service in by_service}
        missing = sorted(service for service in by_service if default not in known[service])
        loc = self._deployment_loc(dep, "driver")
        if missing and len(missing) == len(by_service):
            every = sorted({driver for drivers in known.values() for driver in drivers})
            self.d.error(f"unknown driver '{default}' (known: {', '.join(every)})", loc)
            return
        for service in missing:
            names = ", ".join(f"'{n}'" for n in by_service[service])
            advice = "them drivers of their own" if len(by_service[service]) > 1 else "it a driver of its own"
            self.d.error(f"the {service} service of {names} has no driver '{default}' (known: "
                         f"{', '.join(known[service])}); give {advice}", loc)

    def check_settings(self, name: str, impl: Implementation, dep: SourceDeployment) -> None:
        """A component's settings, when given (`settings: {}` too), as its service's driver will
        validate them at start-up (`driver: auto`: as every hardware driver will). Without settings
        a component runs with the mock and sim drivers only: a warning in a rich deployment for a
        hardware driver, nothing in the seed's plain format."""
        from umlbot.base.registry import AUTO, PREFIXED_DRIVERS, settings_problems

        assert dep.deployment is not None
        entry = dep.deployment.components[name]
        driver = dep.deployment.driver_for(name)
        driver_name = "the hardware drivers" if driver == AUTO else f"driver '{driver}'"
        if "settings" not in entry.model_fields_set:
            # the seed's plain format has no settings; a rich deployment that leaves them out for a
            # hardware driver is told what the robot will ask for
            if dep.root is None or driver in PREFIXED_DRIVERS:
                return
            needed = [".".join(str(part) for part in path) for path, _ in
                      settings_problems(impl.service, driver, {})]
            if needed:
                self.d.warning(f"'{name}' has no settings: {driver_name} need {', '.join(needed)} "
                               "(it runs with the mock and sim drivers only)",
                               self._deployment_loc(dep, "components", name))
            return
        for path, msg in settings_problems(impl.service, driver, entry.settings):
            field = ".".join(str(part) for part in path)
            self.d.error(f"settings of '{name}' ({impl.id}) refused by {driver_name}: "
                         f"{field + ': ' if field else ''}{msg}",
                         self._deployment_loc(dep, "components", name, "settings", *path))

    def check_shared_pins(self, dep: SourceDeployment) -> None:
        """Two components wired to one GPIO: the second service to start would take the pin over."""
        from umlbot.base.deployment import shared_pins

        assert dep.deployment is not None
        for shared in shared_pins(dep.deployment):
            name = shared.component
            if name in self.deployed and shared.first in self.deployed:  # else its entry's own error
                self.d.error(shared.message(),
                             self._deployment_loc(dep, "components", name, "settings", *shared.path))

    # --- swimlanes -----------------------------------------------------------------------------------

    def read_lanes(self) -> None:
        for src in self.source.lanes:
            if src.name in RESERVED:
                self.d.error(f"'{src.name}' is a reserved name; choose another swimlane name", src.loc)
                continue
            if src.name in self.scope.lanes:
                first = self.scope.lanes[src.name].src.loc
                self.d.error(f"duplicate swimlane '{src.name}' (first defined at {first.file}:"
                             f"{first.line})", src.loc)
                continue
            virtual = src.name not in self.source.components
            damaged = src.name in self.source.damage.lanes
            if self.memo is None:
                lane = _Lane(src, virtual=virtual)
                self.read_lane(lane)
            else:
                entry = self.memo.get(src, virtual, damaged)
                if entry is None:
                    entry = self.checked_lane(src, virtual, damaged)
                lane = entry.lane
                self.d.items.extend(entry.problems)
                self.signals |= entry.signals
                self.entries[src.name] = entry
            self.scope.lanes[src.name] = lane
            self.lanes.append(lane)

    def checked_lane(self, src: SourceLane, virtual: bool, damaged: bool) -> _LaneChecks:
        """A swimlane read and its graph checked, for the memo: what depends on its text only."""
        lane = _Lane(src, virtual=virtual)
        outer, outer_signals = self.d, self.signals
        self.d, self.signals = Diagnostics(), set()
        try:
            self.read_lane(lane)
            if not damaged:  # an edge to an unread node is no error of its own
                self.check_graph(lane)
            return _LaneChecks(src, virtual, damaged, lane, self.d.items, self.signals)
        finally:
            self.d, self.signals = outer, outer_signals

    def read_lane(self, lane: _Lane) -> None:
        src = lane.src
        unique: list[SourceNode] = []
        seen: set[str] = set()
        for node in src.nodes:
            if node.id in seen:
                self.d.error(f"duplicate node id '{node.id}' in swimlane '{lane.name}'", node.id_loc)
            else:
                seen.add(node.id)
                unique.append(node)
        for index, node in enumerate(unique):
            following = unique[index + 1].id if index + 1 < len(unique) else None
            self.read_node(lane, node, following)
        starts = [n for n in lane.nodes.values() if n.src.kind == "start"]
        damaged = lane.name in self.source.damage.lanes  # its start or end may be unread
        if not starts:
            if not damaged:
                self.d.error(f"swimlane '{lane.name}' has no start node", src.loc)
        else:
            lane.start = starts[0].id
            for extra in starts[1:]:
                self.d.error(f"duplicate start node '{extra.id}': swimlane '{lane.name}' already "
                             f"starts at '{starts[0].id}'", extra.src.id_loc)
        if not damaged and not any(n.src.kind == "end" for n in lane.nodes.values()):
            self.d.error(f"swimlane '{lane.name}' has no end node", src.loc)

    def scalar(self, fields: YMap, key: str, what: str, required: bool = True) -> YScalar | None:
        node = fields.get(key)
        if node is None:
            if required:
                self.d.error(f"{what} needs '{key}'", fields.loc)
            return None
        if not isinstance(node, YScalar) or node.tag.endswith(":null") or not node.text.strip():
            self.d.error(f"'{key}' of {what} must be a single value", node.loc)
            return None
        return node

    def name_field(self, fields: YMap, key: str, what: str, required: bool = True) -> str | None:
        node = self.scalar(fields, key, what, required)
        if node is None:
            return None
        text = node.text.strip()
        if not text.isidentifier() or not text.isascii() or text in RESERVED:
            self.d.error(f"'{key}' of {what} must be a plain name, got {text!r}", node.loc)
            return None
        return text

    def read_node(self, lane: _Lane, src: SourceNode, following: str | None) -> None:
        node = _Node(src)
        lane.nodes[src.id] = node
        lane.order.append(src.id)
        fields = src.fields
        what = f"{src.kind} node '{src.id}'"
        if src.kind in NEXT_KINDS:
            nxt = self.scalar(fields, "next", what, required=False)
            if nxt is not None:
                node.next, node.next_loc = nxt.text.strip(), nxt.loc
            elif "next" not in fields.items and following is not None:
                node.next, node.next_loc = following, src.loc
            elif "next" not in fields.items:
                self.d.error(f"{what} has no outgoing flow: give it 'next' or put a node after it",
                             src.id_loc)
        if src.kind == "action":
            node.expr = self.scalar(fields, "call", what)
        elif src.kind == "datastore":
            node.name = self.name_field(fields, "name", what)
            node.expr = self.scalar(fields, "value", what)
            if node.name is not None:
                lane.writes.setdefault(node.name, []).append(node.expr)
        elif src.kind == "send":
            node.signal = self.name_field(fields, "signal", what)
            node.expr = self.scalar(fields, "payload", what, required=False)
        elif src.kind == "accept":
            node.signal = self.name_field(fields, "signal", what)
            node.store = self.name_field(fields, "store", what, required=False)
            if node.store is not None:
                lane.writes.setdefault(node.store, []).append(None)
        elif src.kind == "decision":
            self.read_branches(node, fields, what)
        elif src.kind == "fork":
            targets = fields.get("targets")
            if not isinstance(targets, YSeq) or not all(isinstance(t, YScalar) for t in targets.items):
                self.d.error(f"{what} needs 'targets': a list of node ids", (targets or fields).loc)
            else:
                node.targets = [(cast(YScalar, t).text, t.loc) for t in targets.items]
                if len(node.targets) < 2:
                    self.d.error(f"{what} needs at least two targets", targets.loc)
        if node.signal is not None:
            self.signals.add(node.signal)

    def read_branches(self, node: _Node, fields: YMap, what: str) -> None:
        branches = fields.get("branches")
        if not isinstance(branches, YSeq) or not branches.items:
            self.d.error(f"{what} needs 'branches': a list of {{if: <guard>, then: <node>}} and "
                         "{else: <node>}", (branches or fields).loc)
            return
        else_seen: Location | None = None
        for item in branches.items:
            if not isinstance(item, YMap):
                self.d.error("a decision output is {if: <guard>, then: <node>} or {else: <node>}",
                             item.loc)
                continue
            for key in item:
                if key not in ("if", "then", "else"):
                    self.d.error(f"unknown key '{key}' in decision output (expected: if, then, else)",
                                 item.key_loc(key))
            if "else" in item.items:
                if "if" in item.items or "then" in item.items:
                    self.d.error("an else output has no guard: write {else: <node>}", item.loc)
                    continue
                target = self.scalar(item, "else", "the else output")
                if else_seen is not None:
                    self.d.error(f"decision has two else outputs (the first at line {else_seen.line})",
                                 item.loc)
                    continue
                else_seen = item.loc
                node.branches.append(_Branch(None, target.text.strip() if target else None,
                                             target.loc if target else item.loc, item.loc, True))
                continue
            guard_node = item.get("if")
            target = self.scalar(item, "then", "a decision output")
            if not isinstance(guard_node, YScalar) or not guard_node.text.strip():
                if guard_node is None or isinstance(guard_node, YScalar):
                    self.d.error("decision output without guard: write {if: <guard>, then: <node>} or "
                                 "{else: <node>}", item.loc)
                else:
                    self.d.error("a guard is an expression", guard_node.loc)
                if target is not None:
                    node.unguarded.append((target.text.strip(), target.loc))
                continue
            node.branches.append(_Branch(guard_node, target.text.strip() if target else None,
                                         target.loc if target else item.loc, item.loc, False))
        # the else output is taken only when no guard holds, whatever its place in the list
        node.branches.sort(key=lambda b: b.is_else)
        if else_seen is None:
            self.d.warning(f"decision '{node.id}' has no else output: when no guard holds, this flow "
                           "stops", node.src.id_loc)

    # --- expressions -------------------------------------------------------------------------------

    def parse(self, scalar: YScalar) -> tuple[RawExpr, SourceText]:
        """Parse an expression once (datastore values are read twice: to infer types, to check)."""
        cached = self.parsed.get(id(scalar))
        if cached is not None:
            return cached
        where = scalar.content_location()
        # the same text parses to the same tree (offsets are relative to the text): models repeat
        # calls such as `LeftActuator.enabled(true)` many times
        raw = self.trees.get(scalar.text)
        if raw is None:
            raw = parse_expression(scalar.text, where)
            self.trees[scalar.text] = raw
        result = raw, SourceText(scalar.text, where)
        self.parsed[id(scalar)] = result
        return result

    def infer_datastore_types(self) -> None:
        """Give every datastore the join of the types written to it (a fixpoint: values may read
        other datastores, or the same one, as in `count = count + 1`)."""
        parsed: dict[int, tuple[RawExpr, SourceText] | None] = {}  # None: a syntax error
        for lane in self.lanes:
            for name in lane.writes:
                self.scope.datastore_types[(lane.name, name)] = "unknown"
        memo = self.memo
        names_key = self.names_key() if memo is not None else ()
        if memo is not None:
            # the last check's key when equal: then comparing it below is by identity
            names_key = memo.names_key = memo.names_key if memo.names_key == names_key else names_key
        known: dict[int, tuple[YScalar, str, tuple[Any, ...], Type]] = {}
        for _ in range(50):
            changed = False
            read_datastore = False
            for lane in self.lanes:
                for name, values in lane.writes.items():
                    t: Type = "unknown"
                    for scalar in values:
                        if scalar is None:
                            t = _join(t, "any")
                            continue
                        key = id(scalar)
                        if memo is not None:
                            kept = known.get(key) or memo.values.get(key)
                            if kept is not None and kept[0] is scalar and kept[1] == lane.name \
                                    and kept[2] is names_key:
                                known[key] = kept
                                t = _join(t, kept[3])
                                continue
                        if key not in parsed:
                            try:
                                parsed[key] = self.parse(scalar)
                            except ModelError:
                                parsed[key] = None
                        entry = parsed[key]
                        if entry is None:
                            t = _join(t, "any")
                            continue
                        checker = _ExprChecker(self.scope, lane.name, entry[1])
                        try:
                            _, value_type = checker.resolve(entry[0])
                        except ModelError:
                            value_type = "any"
                        read_datastore = read_datastore or checker.read_datastore
                        if value_type == "none":
                            value_type = "any"
                        if memo is not None and not checker.read_datastore:
                            known[key] = (scalar, lane.name, names_key, value_type)
                        t = _join(t, value_type)
                    if t != self.scope.datastore_types[(lane.name, name)]:
                        self.scope.datastore_types[(lane.name, name)] = t
                        changed = True
            if not changed or not read_datastore:
                break  # no value read a datastore: the types cannot change in another pass
        for store, t in self.scope.datastore_types.items():
            if t == "unknown":
                self.scope.datastore_types[store] = "any"
        if memo is not None:
            memo.values = known

    def names_key(self) -> tuple[Any, ...]:
        """`scope_key` without the datastores' types (only which datastores there are): what an
        expression that reads no datastore can depend on."""
        scope = self.scope
        return (tuple(scope.kinds.items()), tuple(scope.impls.items()),
                tuple((name, lane.virtual) for name, lane in scope.lanes.items()),
                tuple(scope.datastore_types), frozenset(scope.damage.lanes),
                bool(scope.damage.empty_files), frozenset(scope.unknown_components),
                scope.components_unknown, scope.lanes_unknown, scope.deployment_unread)

    def expression(self, lane: _Lane, scalar: YScalar, action: bool = False) -> tuple[Data, Type] | None:
        try:
            raw, text = self.parse(scalar)
        except ModelError as exc:
            self.d.add_model_error(exc)
            return None
        checker = _ExprChecker(self.scope, lane.name, text)
        try:
            result: tuple[Data, Type] | None = checker.resolve(raw, action=action)
        except ModelError as exc:
            self.d.add_model_error(exc)
            result = None
        for parts in checker.left_out:
            self.leave_out(*parts)
        for name, loc in checker.missing:
            self.missing_lanes.setdefault(name, loc)
        if result is not None:
            self.lane_calls.extend(checker.lane_calls)
        if self.recording is not None:
            self.recording.left_out += checker.left_out
            self.recording.missing += checker.missing
            if result is not None:
                self.recording.lane_calls += checker.lane_calls
        return result

    def scope_key(self) -> tuple[Any, ...]:
        """Everything outside a swimlane that its expressions can name (`_ExprChecker`): equal
        keys, equal results of the same expressions."""
        scope = self.scope
        return (tuple(scope.kinds.items()), tuple(scope.impls.items()),
                tuple((name, lane.virtual) for name, lane in scope.lanes.items()),
                tuple(scope.datastore_types.items()), frozenset(scope.damage.lanes),
                bool(scope.damage.empty_files), frozenset(scope.unknown_components),
                scope.components_unknown, scope.lanes_unknown, scope.deployment_unread)

    def check_expressions(self) -> None:
        if self.memo is None:
            for lane in self.lanes:
                self.check_lane_expressions(lane)
            return
        key = self.scope_key()
        for lane in self.lanes:
            entry = self.entries[lane.name]
            if entry.scope_key != key:
                # checked again: its nodes get this check's compiled expressions
                for node in lane.nodes.values():
                    node.compiled_expr = None
                    node.compiled_guards = []
                entry.scope_key, entry.built = None, None
                entry.left_out, entry.missing, entry.lane_calls = [], [], []
                outer = self.d
                self.d, self.recording = Diagnostics(), entry
                try:
                    self.check_lane_expressions(lane)
                    entry.expr_problems = self.d.items
                finally:
                    self.d, self.recording = outer, None
                self.d.items.extend(entry.expr_problems)
                entry.scope_key = key
                continue
            self.d.items.extend(entry.expr_problems)
            for parts in entry.left_out:
                self.leave_out(*parts)
            for name, loc in entry.missing:
                self.missing_lanes.setdefault(name, loc)
            self.lane_calls.extend(entry.lane_calls)

    def check_lane_expressions(self, lane: _Lane) -> None:
        for node_id in lane.order:
            node = lane.nodes[node_id]
            kind = node.src.kind
            if kind == "action" and node.expr is not None:
                result = self.expression(lane, node.expr, action=True)
                if result is not None:
                    if result[0]["op"] == "call":
                        node.compiled_expr = result[0]
                    else:
                        self.d.error("an action is a call: Component.feature(args), a virtual "
                                     "swimlane, or a builtin such as msleep(ms)",
                                     node.expr.content_location())
            elif kind in ("datastore", "send") and node.expr is not None:
                result = self.expression(lane, node.expr)
                if result is not None:
                    if result[1] == "none":
                        self.d.error(f"'{node.expr.text.strip()}' gives no value",
                                     node.expr.content_location())
                    else:
                        node.compiled_expr = result[0]
            elif kind == "decision":
                for branch in node.branches:
                    if branch.guard is None:
                        node.compiled_guards.append(None)
                        continue
                    result = self.expression(lane, branch.guard)
                    if result is None:
                        node.compiled_guards.append(None)
                        continue
                    if result[1] not in ("bool", "any"):
                        self.d.error(f"a guard must be a bool, got {result[1]}",
                                     branch.guard.content_location())
                    node.compiled_guards.append(result[0])

    # --- graphs --------------------------------------------------------------------------------------

    def report_empty_files(self) -> None:
        """An empty activity file is a warning; while swimlanes called in the model are defined
        nowhere it is the one error that names them, in place of one "unknown swimlane" per call
        (an emptied file is the likely home of what is missing)."""
        empty = self.source.damage.empty_files
        if not self.missing_lanes:
            for loc in empty:
                self.d.warning("empty activity file", loc)
            return
        names = sorted(self.missing_lanes, key=lambda n: _position(self.missing_lanes[n]))
        listed = ", ".join(f"{name} (first at {_where(self.missing_lanes[name])})"
                           for name in names[:MAX_LISTED])
        if len(names) > MAX_LISTED:
            listed += f" and {len(names) - MAX_LISTED} more"
        count = "1 swimlane" if len(names) == 1 else f"{len(names)} swimlanes"
        self.d.error(f"empty activity file, and the model names {count} defined nowhere: {listed}",
                     empty[0])
        for loc in empty[1:]:
            self.d.error(f"empty activity file (the swimlanes defined nowhere are listed at "
                         f"{_where(empty[0])})", loc)

    def check_graph(self, lane: _Lane) -> None:
        for node_id in lane.order:
            node = lane.nodes[node_id]
            edges: list[tuple[str, Location]] = []
            if node.next is not None and node.next_loc is not None:
                edges.append((node.next, node.next_loc))
            edges += [(b.target, b.target_loc) for b in node.branches if b.target is not None]
            edges += node.unguarded
            edges += node.targets
            for target, loc in edges:
                if target not in lane.nodes:
                    self.d.error(f"flow from '{node_id}' goes to unknown node '{target}'", loc)
                else:
                    lane.incoming.setdefault(target, []).append(node_id)
        if lane.start is None:
            return
        for node_id, preds in lane.incoming.items():
            if node_id == lane.start:
                self.d.error(f"the start node '{node_id}' cannot have incoming flows (from "
                             f"'{preds[0]}')", lane.nodes[node_id].src.id_loc)
        reached = {lane.start}
        queue = deque([lane.start])
        while queue:
            for target in lane.nodes[queue.popleft()].successors():
                if target in lane.nodes and target not in reached:
                    reached.add(target)
                    queue.append(target)
        for node_id in lane.order:
            if node_id not in reached:
                self.d.error(f"node '{node_id}' has no path from the start of swimlane '{lane.name}'",
                             lane.nodes[node_id].src.id_loc)
        self.check_forks(lane, reached)

    def check_forks(self, lane: _Lane, reached: set[str]) -> None:
        """Pair every fork with the one join all its branches reach; report joins that never fire."""
        memo: dict[str, str | None] = {}
        in_progress: set[str] = set()
        branch_preds: dict[str, list[set[str]]] = {}

        def walk(start: str) -> tuple[set[str], set[str]]:
            """The joins one branch reaches, and the nodes from which it enters them."""
            joins: set[str] = set()
            preds: set[str] = set()
            seen: set[str] = set()
            stack: list[tuple[str, str | None]] = [(start, None)]
            while stack:
                node_id, came_from = stack.pop()
                node = lane.nodes.get(node_id)
                if node is None:
                    continue
                if node.src.kind == "join":
                    joins.add(node_id)
                    if came_from is not None:
                        preds.add(came_from)
                    continue
                if node_id in seen:
                    continue
                seen.add(node_id)
                if node.src.kind == "fork":
                    inner = match(node_id)
                    if inner is not None:
                        after = lane.nodes[inner].next
                        if after is not None:
                            stack.append((after, inner))
                    continue
                stack.extend((succ, node_id) for succ in node.successors())
            return joins, preds

        def match(fork_id: str) -> str | None:
            if fork_id in memo:
                return memo[fork_id]
            if fork_id in in_progress:
                return None
            in_progress.add(fork_id)
            fork = lane.nodes[fork_id]
            results = [walk(target) for target, _ in fork.targets if target in lane.nodes]
            in_progress.discard(fork_id)
            all_joins = set().union(*(joins for joins, _ in results)) if results else set()
            found: str | None = None
            if len(all_joins) == 1 and all(joins for joins, _ in results):
                found = next(iter(all_joins))
                branch_preds[fork_id] = [preds for _, preds in results]
            memo[fork_id] = found
            return found

        forks = [n for n in lane.order if lane.nodes[n].src.kind == "fork" and n in reached]
        matched_by: dict[str, str] = {}
        for fork_id in forks:
            fork = lane.nodes[fork_id]
            if len(fork.targets) < 2 or any(t not in lane.nodes for t, _ in fork.targets):
                continue
            join = match(fork_id)
            if join is None:
                results = [walk(t) for t, _ in fork.targets]
                reached_joins = sorted(set().union(*(j for j, _ in results)))
                if not reached_joins:
                    why = "its flows never reach a join"
                else:
                    why = f"its flows reach different joins or none ({', '.join(reached_joins)})"
                self.d.error(f"fork '{fork_id}' has no matching join: {why}", fork.src.id_loc)
                continue
            if join in matched_by:
                self.d.error(f"join '{join}' is the matching join of two forks ('{matched_by[join]}' "
                             f"and '{fork_id}')", fork.src.id_loc)
                continue
            matched_by[join] = fork_id
            lane.fork_join[fork_id] = join
            join_node = lane.nodes[join]
            preds = branch_preds[fork_id]
            for pred in lane.incoming.get(join, []):
                owners = [i for i, p in enumerate(preds) if pred in p]
                if not owners:
                    self.d.error(f"join '{join}' can never fire: the flow from '{pred}' does not come "
                                 f"from fork '{fork_id}'", join_node.src.id_loc)
            for index, p in enumerate(preds):
                if len(p) > 1:
                    names = " and ".join(f"'{x}'" for x in sorted(p))
                    self.d.error(f"join '{join}' can never fire: the flows from {names} come from the "
                                 f"same branch of fork '{fork_id}' (from '{fork.targets[index][0]}'), so "
                                 "only one of them arrives", join_node.src.id_loc)
        for node_id in lane.order:
            node = lane.nodes[node_id]
            if node.src.kind != "join" or node_id in matched_by or node_id not in reached:
                continue
            incoming = lane.incoming.get(node_id, [])
            if len(incoming) > 1:
                self.d.error(f"join '{node_id}' can never fire: its incoming flows "
                             f"({', '.join(incoming)}) do not come from one fork", node.src.id_loc)
            else:
                self.d.warning(f"join '{node_id}' has one incoming flow and no fork; it does nothing",
                               node.src.id_loc)

    def check_recursion(self) -> None:
        """Report each cycle of calls between virtual swimlanes once, at a call that closes it."""
        graph: dict[str, list[_LaneCall]] = {}
        for call in self.lane_calls:
            graph.setdefault(call.caller, []).append(call)
        reported: set[frozenset[str]] = set()
        for origin in sorted(graph):
            # depth-first search for a path back to `origin`
            stack: list[tuple[str, list[_LaneCall]]] = [(origin, [])]
            visited: set[str] = set()
            while stack:
                lane, path = stack.pop()
                for call in graph.get(lane, []):
                    if call.callee == origin:
                        cycle = [*path, call]
                        members = frozenset(c.caller for c in cycle)
                        if members not in reported:
                            reported.add(members)
                            names = " -> ".join([*(c.caller for c in cycle), origin])
                            if len(cycle) == 1:
                                msg = f"virtual swimlane '{origin}' calls itself (recursion is not allowed)"
                            else:
                                msg = f"recursion between virtual swimlanes: {names}"
                            self.d.error(msg, cycle[-1].loc)
                    elif call.callee not in visited:
                        visited.add(call.callee)
                        stack.append((call.callee, [*path, call]))
        # a call may have been in what could not be read, or in the emptied file
        unknown = self.source.damage.calls_unknown or bool(self.missing_lanes)
        called = {call.callee for call in self.lane_calls}
        for each in self.lanes:
            if each.virtual and each.name not in called:
                if unknown:
                    self.leave_out("lanes", "components")
                else:
                    self.d.warning(f"virtual swimlane '{each.name}' is never called", each.src.loc)

    # --- the compiled model ------------------------------------------------------------------------

    def build(self) -> CompiledModel:
        source = self.source
        assert source.deployment is not None and source.deployment.deployment is not None
        deployment = source.deployment.deployment
        components: Data = {}
        for name, kind in sorted(self.scope.kinds.items()):
            impl = self.scope.impls[name]
            entry = deployment.components[name]
            components[name] = {
                "kind": kind, "impl": impl.id, "service": impl.service,
                "driver": deployment.driver_for(name), "settings": dict(entry.settings),
                "features": sorted(impl.features),
                "ports": {port: feature
                          for port, (feature, _) in sorted(source.components[name].ports.items())},
                "safe_stop": [{"feature": feature, "args": list(args)} for feature, args in impl.safe_stop],
            }
        links = [
            {"id": link.id, "source_component": link.source.component, "source_port": link.source.port,
             "target_component": link.target.component, "target_port": link.target.port}
            for link in source.links if link.source is not None and link.target is not None
        ]
        lanes = {lane.name: self.build_lane(lane) for lane in sorted(self.lanes, key=lambda x: x.name)}
        return CompiledModel.model_validate({
            "name": deployment.robot or source.name, "source_hash": source.source_hash,
            "call_timeout_s": source.call_timeout_s, "components": components, "links": links,
            "signals": sorted(self.signals), "lanes": lanes,
        })

    def build_lane(self, lane: _Lane) -> Data | Lane:
        """The compiled swimlane: as data (validated with the whole model), or with a memo the
        `Lane` validated when it was last built (the model takes it as it is)."""
        entry = self.entries.get(lane.name)
        if entry is not None:
            if entry.built is None:
                entry.built = Lane.model_validate(self.built_lane(lane))
            return entry.built
        return self.built_lane(lane)

    def built_lane(self, lane: _Lane) -> Data:
        assert lane.start is not None
        return {
            "name": lane.name, "virtual": lane.virtual,
            "component": None if lane.virtual else lane.name, "start": lane.start,
            "nodes": {node_id: self.build_node(lane, lane.nodes[node_id]) for node_id in lane.order},
            "datastores": sorted(lane.writes), "file": lane.src.file, "line": lane.src.loc.line,
        }

    def build_node(self, lane: _Lane, node: _Node) -> Data:
        kind = node.src.kind
        data: Data = {"id": node.id, "line": node.src.loc.line, "kind": kind}
        text = node.expr.text.strip() if node.expr is not None else ""
        if kind in NEXT_KINDS:
            data["next"] = node.next or ""
        if kind == "start":
            data["label"] = "start"
        elif kind == "end":
            data["label"] = "end"
        elif kind == "action":
            data.update(label=text, call=node.compiled_expr)
        elif kind == "datastore":
            data.update(label=f"{node.name} = {text}", name=node.name, value=node.compiled_expr)
        elif kind == "decision":
            data["label"] = node.id
            data["branches"] = [
                {"guard": guard, "target": b.target or "", "line": b.loc.line,
                 "label": b.guard.text.strip() if b.guard is not None else "else"}
                for b, guard in zip(node.branches, node.compiled_guards, strict=True)
            ]
        elif kind == "fork":
            data.update(label="fork", targets=[t for t, _ in node.targets], join=lane.fork_join[node.id])
        elif kind == "join":
            data.update(label="join", incoming=sorted(lane.incoming.get(node.id, [])))
        elif kind == "send":
            data.update(label=f"send {node.signal}" + (f"({text})" if text else ""), signal=node.signal,
                        payload=node.compiled_expr)
        else:
            data.update(label=f"accept {node.signal}" + (f" -> {node.store}" if node.store else ""),
                        signal=node.signal, store=node.store)
        return data


def _position(loc: Location) -> tuple[str, int, int]:
    return loc.file, loc.line, loc.column


def _where(loc: Location) -> str:
    return f"{loc.file}:{loc.line}:{loc.column}"


def check_source(source: SourceModel, diagnostics: Diagnostics,
                 memo: CheckMemo | None = None) -> CompiledModel | None:
    """Run every check; the compiled model when there is no error, else None.

    A file that could not be read (its error is reported) leaves out only the checks that depend
    on what it may hold ("unknown component", "unknown swimlane", "never called" would be
    follow-ons of it); its error says how many.
    """
    checker = _Checker(source, diagnostics, memo)
    checker.check_components()
    checker.check_deployment()
    checker.read_lanes()
    checker.infer_datastore_types()
    checker.check_expressions()
    checker.report_empty_files()
    if memo is None:  # with a memo, each swimlane's graph is checked as it is read
        for lane in checker.lanes:
            if lane.name not in source.damage.lanes:  # an edge to an unread node is no error of its own
                checker.check_graph(lane)
    checker.check_recursion()
    checker.report_left_out()
    if memo is not None:
        memo.lanes = {id(entry.src): entry for entry in checker.entries.values()}
    if diagnostics.has_errors:
        return None
    return checker.build()


__all__ = ["CheckMemo", "Type", "check_source"]
