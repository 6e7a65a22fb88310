"""Importing a library without the modules it imports only for features umlbot does not use.

A service process should hold only what it runs (docs/performance.md, "Memory"): structlog
imports asyncio, rich and greenlet, paho imports ssl and urllib.request (with http.client and
email), each for a feature a plain-TCP service never touches. `import_lean` imports a library
with such modules *deferred* (a stand-in module in `sys.modules` that imports the real one on the
first attribute use: `ssl.create_default_context()` in paho's `tls_set` imports ssl then) or
*blocked* (the library sees an ImportError and goes without, as it does when they are not
installed). The stand-ins leave `sys.modules` when the import is done, so a later `import ssl`
anywhere gets the real module.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Iterable, Mapping
from typing import Any


class Unraised(Exception):
    """What a `Deferred` module's *unraised* exception names stand for until the real module is
    imported: nothing raises it, so an `except` clause naming it catches nothing — as it must,
    since only objects of the real module (which is not loaded yet) raise the real exception."""


class Deferred(types.ModuleType):
    """Stands in for module `name` inside one library; imports the real one on first attribute use
    (through the import system, with its locks), so the library works unchanged.

    `unraised` names exception classes that only the module's own objects raise (ssl's
    `SSLWantReadError`: only an SSL socket raises it, and making one imports ssl). Until the real
    module is imported by anyone, such a name gives `Unraised` instead of importing it: an
    `except` clause that names it (paho's socket reads and writes) does not load the module."""

    def __init__(self, name: str, unraised: Iterable[str] = ()) -> None:
        super().__init__(name)
        self._unraised = frozenset(unraised)

    def __getattr__(self, name: str) -> Any:
        if sys.modules.get(self.__name__) is self:
            raise AttributeError(f"{self.__name__}.{name} used while a library was being imported "
                                 "with it deferred (umlbot.base.lazy)")
        if name in self._unraised and not isinstance(sys.modules.get(self.__name__), types.ModuleType):
            return Unraised
        return getattr(importlib.import_module(self.__name__), name)


def import_lean(module: str, deferred: Iterable[str] = (), blocked: Iterable[str] = (),
                unraised: Mapping[str, Iterable[str]] | None = None,
                provided: Mapping[str, Mapping[str, Any]] | None = None) -> types.ModuleType:
    """Import `module` with the modules in `deferred` replaced by `Deferred` stand-ins and those in
    `blocked` made to raise ImportError, unless they are imported already (then the library gets
    the real ones). `unraised` maps a deferred module to its exception names that must not import
    it (see `Deferred`). `provided` maps a module to the names the library takes from it with
    `from module import name`, each with what it gets instead (a stand-in module holding only
    those)."""
    stand_ins: dict[str, types.ModuleType | None] = {}
    for name, attributes in (provided or {}).items():
        if name not in sys.modules:
            providing = types.ModuleType(name)
            for attribute, value in attributes.items():
                setattr(providing, attribute, value)
            stand_ins[name] = providing
    for name in blocked:
        if name not in sys.modules:
            stand_ins[name] = None  # `import name` raises ImportError
    for name in deferred:
        if name not in sys.modules:
            stand_ins[name] = Deferred(name, (unraised or {}).get(name, ()))
    sys.modules.update(stand_ins)  # type: ignore[arg-type]  # None blocks an import
    try:
        return importlib.import_module(module)
    finally:
        for name, stand_in in stand_ins.items():
            if sys.modules.get(name) is stand_in:
                del sys.modules[name]


def lazy_attributes(package: str, table: dict[str, str]) -> Callable[[str], Any]:
    """A module `__getattr__` (PEP 562) for a package's front door: `name` is imported from the
    module `table[name]` on first use, so that a heavy part (the embedded broker, the sim's runner)
    loads only in the processes that use it. Declare the same names under `TYPE_CHECKING` for the
    type checker."""

    def __getattr__(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(module), name)

    return __getattr__
