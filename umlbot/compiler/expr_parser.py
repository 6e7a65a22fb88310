"""The expression language's tokenizer and parser (hand-written, recursive descent).

`parse_expression` turns source text into a positioned syntax tree (`RawExpr`) whose names are
not resolved yet; the checker resolves names and types and produces `umlbot.compiler.expr` trees.
Errors are `ModelError`s pointing at the exact line and column; nesting is bounded so hostile
input gives a `ModelError`, never a `RecursionError`. Nothing is ever eval'd.

Limits: `MAX_LENGTH` characters; `MAX_DEPTH` levels of nesting (parentheses, `not`, `-`, call
arguments, an operand of a tighter operator); and `MAX_TREE_HEIGHT` operators one inside the other,
where a chain `a + b + c` is not nesting but still one level per operator (the compiled tree is
binary, and the compiled file's reader takes about 250 levels).

Grammar, loosest binding first::

    expr     := or
    or       := and ("or" and)*
    and      := not ("and" not)*
    not      := "not" not | compare
    compare  := sum (("==" | "!=" | "<" | "<=" | ">" | ">=") sum)?      # no chaining
    sum      := product (("+" | "-") product)*
    product  := unary (("*" | "/" | "%") unary)*
    unary    := "-" unary | primary
    primary  := NUMBER | STRING | "true" | "false" | "null" | "(" expr ")"
              | NAME ("." NAME)? ("(" [expr ("," expr)*] ")")?
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from umlbot.base.diagnostics import Location
from umlbot.base.errors import ModelError

MAX_DEPTH = 64
MAX_TREE_HEIGHT = 200
MAX_LENGTH = 10_000

KEYWORDS = {"and", "or", "not", "true", "false", "True", "False", "null"}
COMPARISONS = ("==", "!=", "<=", ">=", "<", ">")
DIGITS = frozenset("0123456789")
SYMBOLS = ("==", "!=", "<=", ">=", "<", ">", "+", "-", "*", "/", "%", "(", ")", ",", ".")
SYMBOL_SET = frozenset(SYMBOLS)
TWO_CHAR_SYMBOLS = frozenset(s for s in SYMBOLS if len(s) == 2)


@dataclass(slots=True)
class Token:
    kind: str  # "num", "str", "name", "op", "end"
    text: str
    offset: int
    value: object = None


@dataclass(slots=True)
class RConst:
    value: bool | int | float | str | None
    offset: int


@dataclass(slots=True)
class RName:
    """`name` or `Prefix.name`; `offsets` holds where each part starts."""

    parts: tuple[str, ...]
    offsets: tuple[int, ...]

    @property
    def offset(self) -> int:
        return self.offsets[0]

    @property
    def dotted(self) -> str:
        return ".".join(self.parts)


@dataclass(slots=True)
class RCall:
    name: RName
    args: tuple[RawExpr, ...]
    offset: int


@dataclass(slots=True)
class RUnary:
    operator: str
    operand: RawExpr
    offset: int


@dataclass(slots=True)
class RBinary:
    operator: str
    left: RawExpr
    right: RawExpr
    offset: int  # where the operator is


RawExpr = RConst | RName | RCall | RUnary | RBinary


class SourceText:
    """An expression's text and where it starts, to turn offsets into file positions."""

    def __init__(self, text: str, where: Location) -> None:
        self.text = text
        self.where = where

    def location(self, offset: int) -> Location:
        before = self.text[:offset]
        newlines = before.count("\n")
        if newlines:
            return Location(self.where.file, self.where.line + newlines, offset - before.rfind("\n"))
        return Location(self.where.file, self.where.line, self.where.column + offset)

    def error(self, message: str, offset: int) -> ModelError:
        loc = self.location(offset)
        return ModelError(message, loc.file, loc.line, loc.column)


_TOKEN = re.compile(
    r"""(?P<ws>[ \t\r\n]+)
      | (?P<num>(?:[0-9]+(?:\.[0-9]+)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)
      | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
      | (?P<str>'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*")
      | (?P<op>==|!=|<=|>=|[<>+\-*/%(),.])""",
    re.VERBOSE | re.DOTALL,
)
_ESCAPES = {"n": "\n", "t": "\t", "\\": "\\", "'": "'", '"': '"'}
_HINTS = {"&": " (write 'and')", "|": " (write 'or')", "!": " (write 'not')", "=": " (write '==')"}
_NAME_CHAR = re.compile(r"[A-Za-z0-9_]")


def _unescape(src: SourceText, literal: str, offset: int) -> str:
    body = literal[1:-1]
    if "\\" not in body:
        return body
    out: list[str] = []
    i = 0
    while i < len(body):
        c = body[i]
        if c == "\\":
            escape = body[i + 1]
            mapped = _ESCAPES.get(escape)
            if mapped is None:
                raise src.error(f"unknown escape '\\{escape}' in string", offset + 1 + i)
            out.append(mapped)
            i += 2
        else:
            out.append(c)
            i += 1
    return "".join(out)


def tokenize(src: SourceText) -> list[Token]:
    """Split the text into tokens; raises `ModelError` at the first character that fits nothing."""
    text = src.text
    tokens: list[Token] = []
    i, n = 0, len(text)
    match = _TOKEN.match
    while i < n:
        m = match(text, i)
        if m is None:
            ch = text[i]
            if ch in "'\"":
                raise src.error("string not closed", i)
            raise src.error(f"unexpected character {ch!r}{_HINTS.get(ch, '')}", i)
        kind = m.lastgroup
        end = m.end()
        if kind == "name" or kind == "op":
            tokens.append(Token(kind, m.group(), i))
        elif kind == "num":
            literal = m.group()
            if end < n and _NAME_CHAR.match(text, end):
                raise src.error(f"invalid number {text[i:end + 1]!r}", i)
            if len(literal) > 40:
                raise src.error("number too long", i)
            is_float = "." in literal or "e" in literal or "E" in literal
            tokens.append(Token("num", literal, i, float(literal) if is_float else int(literal)))
        elif kind == "str":
            literal = m.group()
            tokens.append(Token("str", literal, i, _unescape(src, literal, i)))
        i = end
    tokens.append(Token("end", "", n))
    return tokens


#: binding power of each binary operator: a higher one binds tighter.
_BINARY_POWER = {"or": 1, "and": 2, "==": 4, "!=": 4, "<": 4, "<=": 4, ">": 4, ">=": 4,
                 "+": 5, "-": 5, "*": 6, "/": 6, "%": 6}
_NOT_POWER = 3  # `not a == b` is `not (a == b)`; `not a and b` is `(not a) and b`
_NEG_POWER = 7  # `-a * b` is `(-a) * b`


class _Parser:
    """A Pratt parser: one loop per binding power instead of one function per level."""

    def __init__(self, src: SourceText) -> None:
        self.src = src
        self.tokens = tokenize(src)
        self.pos = 0
        self.depth = 0

    def advance(self) -> Token:
        tok = self.tokens[self.pos]
        if tok.kind != "end":
            self.pos += 1
        return tok

    def unexpected(self, wanted: str) -> ModelError:
        tok = self.tokens[self.pos]
        found = "end of expression" if tok.kind == "end" else repr(tok.text)
        return self.src.error(f"{wanted}, found {found}", tok.offset)

    def enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.src.error(f"expression nested too deeply (more than {MAX_DEPTH} levels)",
                                 self.tokens[self.pos].offset)

    def parse(self) -> RawExpr:
        if self.tokens[0].kind == "end":
            raise self.src.error("empty expression", 0)
        expr = self.expression(0)
        if self.tokens[self.pos].kind != "end":
            raise self.unexpected("expected an operator or the end of the expression")
        return expr

    def binary_power(self, tok: Token) -> int:
        if tok.kind == "op" or (tok.kind == "name" and tok.text in ("and", "or")):
            return _BINARY_POWER.get(tok.text, 0)
        return 0

    def expression(self, min_power: int) -> RawExpr:
        left = self.prefix()
        while True:
            tok = self.tokens[self.pos]
            power = self.binary_power(tok)
            if power <= min_power:
                return left
            self.advance()
            self.enter()
            right = self.expression(power)
            self.depth -= 1
            left = RBinary(tok.text, left, right, tok.offset)
            if power == 4 and self.binary_power(self.tokens[self.pos]) == 4:
                raise self.src.error("comparisons cannot be chained; combine them with 'and'",
                                     self.tokens[self.pos].offset)

    def prefix(self) -> RawExpr:
        tok = self.tokens[self.pos]
        kind = tok.kind
        if kind == "name":
            text = tok.text
            if text == "not":
                self.advance()
                self.enter()
                operand = self.expression(_NOT_POWER)
                self.depth -= 1
                return RUnary("not", operand, tok.offset)
            if text in ("true", "True", "false", "False"):
                self.advance()
                return RConst(text in ("true", "True"), tok.offset)
            if text == "null":
                self.advance()
                return RConst(None, tok.offset)
            if text in KEYWORDS:
                raise self.unexpected("expected a value")
            return self.name()
        if kind == "num" or kind == "str":
            self.advance()
            assert isinstance(tok.value, int | float | str)
            return RConst(tok.value, tok.offset)
        if kind == "op":
            if tok.text == "-":
                self.advance()
                self.enter()
                operand = self.expression(_NEG_POWER)
                self.depth -= 1
                return RUnary("-", operand, tok.offset)
            if tok.text == "(":
                self.advance()
                self.enter()
                inner = self.expression(0)
                self.depth -= 1
                if not (self.tokens[self.pos].kind == "op" and self.tokens[self.pos].text == ")"):
                    raise self.unexpected("expected ')'")
                self.advance()
                return inner
        raise self.unexpected("expected a value")

    def is_op(self, text: str) -> bool:
        tok = self.tokens[self.pos]
        return tok.kind == "op" and tok.text == text

    def name(self) -> RawExpr:
        first = self.advance()
        parts, offsets = [first.text], [first.offset]
        while self.is_op("."):
            self.advance()
            tok = self.tokens[self.pos]
            if tok.kind != "name" or tok.text in KEYWORDS:
                raise self.unexpected("expected a name after '.'")
            self.advance()
            parts.append(tok.text)
            offsets.append(tok.offset)
        if len(parts) > 2:
            raise self.src.error(
                f"'{'.'.join(parts)}' has too many parts: write name, Lane.name or "
                "Component.feature(...)", first.offset)
        name = RName(tuple(parts), tuple(offsets))
        if not self.is_op("("):
            return name
        self.advance()
        self.enter()
        args: list[RawExpr] = []
        if not self.is_op(")"):
            args.append(self.expression(0))
            while self.is_op(","):
                self.advance()
                args.append(self.expression(0))
        self.depth -= 1
        if not self.is_op(")"):
            raise self.unexpected("expected ',' or ')'")
        self.advance()
        return RCall(name, tuple(args), first.offset)


def parse_expression(text: str, where: Location | None = None) -> RawExpr:
    """Parse one expression; `where` is the position of its first character in the file.

    Raises `ModelError` (with line and column) for any syntax error.
    """
    src = SourceText(text, where or Location("<expression>", 1, 1))
    if len(text) > MAX_LENGTH:
        raise src.error(f"expression too long ({len(text)} characters, at most {MAX_LENGTH})", 0)
    expr = _Parser(src).parse()
    if len(text) > MAX_TREE_HEIGHT:  # a tree higher than MAX_TREE_HEIGHT needs more characters
        _check_height(expr, src)
    return expr


def _children(expr: RawExpr) -> tuple[RawExpr, ...]:
    if isinstance(expr, RCall):
        return expr.args
    if isinstance(expr, RUnary):
        return (expr.operand,)
    if isinstance(expr, RBinary):
        return (expr.left, expr.right)
    return ()


def _check_height(expr: RawExpr, src: SourceText) -> None:
    """Refuse trees higher than MAX_TREE_HEIGHT, without recursion. Nesting is bounded by the
    parser already, but not long operator chains (`a + b + c + ...`), nor chains inside the
    operands of chains: ten parenthesised chains of 199 operators, one inside the next, is a
    tree 1 990 high with no chain over 199 — the error names the height, not a chain."""
    stack: list[tuple[RawExpr, int]] = [(expr, 0)]  # (node, operators above it)
    while stack:
        node, above = stack.pop()
        children = _children(node)
        if children and above >= MAX_TREE_HEIGHT:
            raise src.error(f"expression tree too high: more than {MAX_TREE_HEIGHT} operators one "
                            "inside another (a + b + c has 2, and so has (a + b) * c: chains and "
                            "the parts nested in them add up); split it with a datastore",
                            node.offset)
        stack.extend((child, above + 1) for child in children)
