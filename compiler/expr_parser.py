"""The expression language's tokenizer and parser (hand-written, recursive descent).

`parse_expression` turns source text into a positioned syntax tree (`RawExpr`) whose names are
not resolved yet; the checker resolves names and types and produces `compiler.expr` trees.
Errors are `ModelError`s pointing at the exact line and column; nesting is bounded so hostile
input gives a `ModelError`, never a `RecursionError`. Nothing is ever eval'd.

Grammar, loosest binding first::

    expr     := or
    or       := and ("or" and)*
    and      := not ("and" not)*
    not      := "not" not | compare
    compare  := sum (("==" | "!=" | "<" | "<=" | ">" | ">=") sum)?      # no chaining
    sum      := product (("+" | "-") product)*
    product  := unary (("*" | "/" | "%") unary)*
    unary    := "-" unary | primary
    primary  := NUMBER | STRING | "true" | "false" | "(" expr ")"
              | NAME ("." NAME)? ("(" [expr ("," expr)*] ")")?
"""

from __future__ import annotations

from dataclasses import dataclass

from compiler.diagnostics import Location
from umlbot.errors import ModelError

MAX_DEPTH = 64
MAX_TREE_DEPTH = 100
MAX_LENGTH = 10_000

KEYWORDS = {"and", "or", "not", "true", "false", "True", "False"}
COMPARISONS = ("==", "!=", "<=", ">=", "<", ">")
SYMBOLS = ("==", "!=", "<=", ">=", "<", ">", "+", "-", "*", "/", "%", "(", ")", ",", ".")


@dataclass(frozen=True)
class Token:
    kind: str  # "num", "str", "name", "op", "end"
    text: str
    offset: int
    value: object = None


@dataclass(frozen=True)
class RConst:
    value: bool | int | float | str
    offset: int


@dataclass(frozen=True)
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


@dataclass(frozen=True)
class RCall:
    name: RName
    args: tuple[RawExpr, ...]
    offset: int


@dataclass(frozen=True)
class RUnary:
    operator: str
    operand: RawExpr
    offset: int


@dataclass(frozen=True)
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


def tokenize(src: SourceText) -> list[Token]:
    """Split the text into tokens; raises `ModelError` at the first character that fits nothing."""
    text = src.text
    tokens: list[Token] = []
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        if ch in " \t\r\n":
            i += 1
            continue
        if ch.isdigit() or (ch == "." and i + 1 < n and text[i + 1].isdigit()):
            start = i
            while i < n and text[i].isdigit():
                i += 1
            is_float = False
            if i < n and text[i] == "." and i + 1 < n and text[i + 1].isdigit():
                is_float = True
                i += 1
                while i < n and text[i].isdigit():
                    i += 1
            if i < n and text[i] in "eE":
                j = i + 1
                if j < n and text[j] in "+-":
                    j += 1
                if j < n and text[j].isdigit():
                    is_float = True
                    i = j
                    while i < n and text[i].isdigit():
                        i += 1
            if i < n and (text[i].isalnum() or text[i] == "_"):
                raise src.error(f"invalid number {text[start:i + 1]!r}", start)
            literal = text[start:i]
            if len(literal) > 40:
                raise src.error("number too long", start)
            value: object = float(literal) if is_float else int(literal)
            tokens.append(Token("num", literal, start, value))
            continue
        if ch.isascii() and (ch.isalpha() or ch == "_"):
            start = i
            while i < n and text[i].isascii() and (text[i].isalnum() or text[i] == "_"):
                i += 1
            tokens.append(Token("name", text[start:i], start))
            continue
        if ch in "'\"":
            start = i
            i += 1
            chars: list[str] = []
            while True:
                if i >= n:
                    raise src.error("string not closed", start)
                c = text[i]
                if c == ch:
                    i += 1
                    break
                if c == "\\":
                    if i + 1 >= n:
                        raise src.error("string not closed", start)
                    escape = text[i + 1]
                    mapped = {"n": "\n", "t": "\t", "\\": "\\", "'": "'", '"': '"'}.get(escape)
                    if mapped is None:
                        raise src.error(f"unknown escape '\\{escape}' in string", i)
                    chars.append(mapped)
                    i += 2
                    continue
                chars.append(c)
                i += 1
            tokens.append(Token("str", text[start:i], start, "".join(chars)))
            continue
        for symbol in SYMBOLS:
            if text.startswith(symbol, i):
                tokens.append(Token("op", symbol, i))
                i += len(symbol)
                break
        else:
            hint = {"&": " (write 'and')", "|": " (write 'or')", "!": " (write 'not')", "=": " (write '==')"}
            raise src.error(f"unexpected character {ch!r}{hint.get(ch, '')}", i)
    tokens.append(Token("end", "", n))
    return tokens


class _Parser:
    def __init__(self, src: SourceText) -> None:
        self.src = src
        self.tokens = tokenize(src)
        self.pos = 0
        self.depth = 0

    @property
    def tok(self) -> Token:
        return self.tokens[self.pos]

    def advance(self) -> Token:
        tok = self.tokens[self.pos]
        if tok.kind != "end":
            self.pos += 1
        return tok

    def at(self, *texts: str) -> bool:
        tok = self.tok
        return tok.kind in ("op", "name") and tok.text in texts

    def expect(self, text: str) -> Token:
        if not (self.tok.kind == "op" and self.tok.text == text):
            raise self.unexpected(f"expected '{text}'")
        return self.advance()

    def unexpected(self, wanted: str) -> ModelError:
        tok = self.tok
        found = "end of expression" if tok.kind == "end" else repr(tok.text)
        return self.src.error(f"{wanted}, found {found}", tok.offset)

    def enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.src.error(f"expression nested too deeply (more than {MAX_DEPTH} levels)",
                                 self.tok.offset)

    def parse(self) -> RawExpr:
        if self.tok.kind == "end":
            raise self.src.error("empty expression", 0)
        expr = self.parse_or()
        if self.tok.kind != "end":
            raise self.unexpected("expected an operator or the end of the expression")
        return expr

    def parse_or(self) -> RawExpr:
        left = self.parse_and()
        while self.tok.kind == "name" and self.tok.text == "or":
            op = self.advance()
            left = RBinary("or", left, self.parse_and(), op.offset)
        return left

    def parse_and(self) -> RawExpr:
        left = self.parse_not()
        while self.tok.kind == "name" and self.tok.text == "and":
            op = self.advance()
            left = RBinary("and", left, self.parse_not(), op.offset)
        return left

    def parse_not(self) -> RawExpr:
        if self.tok.kind == "name" and self.tok.text == "not":
            op = self.advance()
            self.enter()
            operand = self.parse_not()
            self.depth -= 1
            return RUnary("not", operand, op.offset)
        return self.parse_compare()

    def parse_compare(self) -> RawExpr:
        left = self.parse_sum()
        if self.tok.kind == "op" and self.tok.text in COMPARISONS:
            op = self.advance()
            right = self.parse_sum()
            if self.tok.kind == "op" and self.tok.text in COMPARISONS:
                raise self.src.error("comparisons cannot be chained; combine them with 'and'",
                                     self.tok.offset)
            return RBinary(op.text, left, right, op.offset)
        return left

    def parse_sum(self) -> RawExpr:
        left = self.parse_product()
        while self.tok.kind == "op" and self.tok.text in ("+", "-"):
            op = self.advance()
            left = RBinary(op.text, left, self.parse_product(), op.offset)
        return left

    def parse_product(self) -> RawExpr:
        left = self.parse_unary()
        while self.tok.kind == "op" and self.tok.text in ("*", "/", "%"):
            op = self.advance()
            left = RBinary(op.text, left, self.parse_unary(), op.offset)
        return left

    def parse_unary(self) -> RawExpr:
        if self.tok.kind == "op" and self.tok.text == "-":
            op = self.advance()
            self.enter()
            operand = self.parse_unary()
            self.depth -= 1
            return RUnary("-", operand, op.offset)
        return self.parse_primary()

    def parse_primary(self) -> RawExpr:
        tok = self.tok
        if tok.kind in ("num", "str"):
            self.advance()
            assert isinstance(tok.value, bool | int | float | str)
            return RConst(tok.value, tok.offset)
        if tok.kind == "op" and tok.text == "(":
            self.advance()
            self.enter()
            inner = self.parse_or()
            self.depth -= 1
            self.expect(")")
            return inner
        if tok.kind == "name":
            if tok.text in ("true", "True", "false", "False"):
                self.advance()
                return RConst(tok.text.lower() == "true", tok.offset)
            if tok.text in KEYWORDS:
                raise self.unexpected("expected a value")
            return self.parse_name()
        raise self.unexpected("expected a value")

    def parse_name(self) -> RawExpr:
        first = self.advance()
        parts, offsets = [first.text], [first.offset]
        while self.tok.kind == "op" and self.tok.text == ".":
            self.advance()
            tok = self.tok
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
        if not (self.tok.kind == "op" and self.tok.text == "("):
            return name
        self.advance()
        self.enter()
        args: list[RawExpr] = []
        if not (self.tok.kind == "op" and self.tok.text == ")"):
            args.append(self.parse_or())
            while self.tok.kind == "op" and self.tok.text == ",":
                self.advance()
                args.append(self.parse_or())
        self.depth -= 1
        if not (self.tok.kind == "op" and self.tok.text == ")"):
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
    """Refuse trees deeper than MAX_TREE_DEPTH (long operator chains nest too), without recursion."""
    stack: list[tuple[RawExpr, int]] = [(expr, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_TREE_DEPTH:
            raise src.error(f"expression nested too deeply (more than {MAX_TREE_DEPTH} levels)",
                            node.offset)
        stack.extend((child, depth + 1) for child in _children(node))
