"""umlbot.base.lazy.import_lean: deferred, blocked and unraised modules, on a library written here."""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from umlbot.base.lazy import Unraised, import_lean

LIBRARY = """
import lazydep
try:
    import lazyextra
except ImportError:
    lazyextra = None

def guarded(error):
    try:
        raise error
    except lazydep.RareError:
        return "caught"

def use():
    return lazydep.VALUE
"""
DEPENDENCY = """
VALUE = 42
class RareError(Exception):
    pass
"""


@pytest.fixture
def library(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    (tmp_path / "lazylib.py").write_text(textwrap.dedent(LIBRARY))
    (tmp_path / "lazydep.py").write_text(textwrap.dedent(DEPENDENCY))
    (tmp_path / "lazyextra.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    for name in ("lazylib", "lazydep", "lazyextra"):
        sys.modules.pop(name, None)


def test_deferred_module_loads_on_first_use_and_blocked_one_is_missing(library: None) -> None:
    lib = import_lean("lazylib", deferred=("lazydep",), blocked=("lazyextra",))
    assert "lazydep" not in sys.modules and "lazyextra" not in sys.modules
    assert lib.lazyextra is None  # the library went without it, as if not installed
    assert lib.use() == 42  # the first attribute use imports the real module
    assert "lazydep" in sys.modules


def test_an_except_clause_naming_an_unraised_exception_does_not_load_the_module(library: None) -> None:
    lib = import_lean("lazylib", deferred=("lazydep",), unraised={"lazydep": ("RareError",)})
    with pytest.raises(ValueError):
        lib.guarded(ValueError("not the rare one"))
    assert "lazydep" not in sys.modules  # the except clause was evaluated without importing it
    assert lib.lazydep.RareError is Unraised
    real = __import__("lazydep")  # once anything imports it, the real class is named
    assert lib.lazydep.RareError is real.RareError
    assert lib.guarded(real.RareError()) == "caught"
