"""Generating the mutants of :mod:`tools.mutate` (docs/contributor_guide.md, "How to test"):
each mutant is one small change to one module's source, found on the syntax tree.

An arithmetic or comparison operator swapped, ``and``/``or`` exchanged, a unary minus or ``not``
dropped, a number changed (an integer by one, a float by a factor of 2, a tolerance below 1e-3 by
10), a numpy reduction or function swapped for its twin (max/min, argmin/argmax, any/all,
cos/sin, sum/mean) or ``abs`` dropped. Docstrings, strings, f-strings, annotations, decorators,
imports and ``__all__`` are left alone. :func:`find_mutants` lists a module's mutants in source
order, :func:`sample` takes a seeded share of them and :meth:`Mutant.apply` writes one into the
source.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

_BINOP_SWAP: dict[type, type] = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.Pow: ast.Mult,
    ast.FloorDiv: ast.Div,
    ast.Mod: ast.FloorDiv,
}

_CMP_SWAP: dict[type, type] = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
}

_NAME_SWAP: dict[str, str] = {
    "max": "min",
    "min": "max",
    "maximum": "minimum",
    "minimum": "maximum",
    "argmin": "argmax",
    "argmax": "argmin",
    "any": "all",
    "all": "any",
    "cos": "sin",
    "sin": "cos",
    "sum": "mean",
    "mean": "sum",
    "floor": "ceil",
    "ceil": "floor",
}


@dataclass(frozen=True)
class Mutant:
    """One mutation: the source span it replaces and the replacement text."""

    path: str
    line: int
    col: int
    end_line: int
    end_col: int
    original: str  #: the source text replaced
    replacement: str
    operator: str  #: which kind of mutation

    @property
    def label(self) -> str:
        """How reports name the mutant: path, line, operator and the change."""
        return (
            f"{self.path}:{self.line} [{self.operator}] {self.original!r} -> {self.replacement!r}"
        )

    def apply(self, source: str) -> str:
        """``source`` with this mutant's span replaced."""
        lines = source.splitlines(keepends=True)
        start = sum(len(s) for s in lines[: self.line - 1]) + _byte_col(
            lines[self.line - 1], self.col
        )
        end = sum(len(s) for s in lines[: self.end_line - 1]) + _byte_col(
            lines[self.end_line - 1], self.end_col
        )
        return source[:start] + self.replacement + source[end:]


def _byte_col(line: str, col: int) -> int:
    """ast column offsets count UTF-8 bytes; convert to a character index in ``line``."""
    return len(line.encode("utf-8")[:col].decode("utf-8", errors="ignore"))


def _skipped_nodes(tree: ast.Module) -> set[int]:
    """ids of nodes never mutated: docstrings, f-strings, annotations, decorators, imports."""
    skip: set[int] = set()

    def mark(node: ast.AST | None) -> None:
        if node is not None:
            skip.update(id(n) for n in ast.walk(node))

    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                mark(body[0])
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            for d in node.decorator_list:
                mark(d)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            mark(node.returns)
            for a in (*node.args.args, *node.args.kwonlyargs, *node.args.posonlyargs):
                mark(a.annotation)
        if isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        if isinstance(node, ast.JoinedStr | ast.Import | ast.ImportFrom):
            mark(node)
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            mark(node)
    return skip


def _number_mutation(x: int | float) -> int | float:
    """An integer plus one; a float times 2 (a tolerance below 1e-3 times 10; 0.0 becomes 1.0)."""
    if isinstance(x, int):
        return x + 1
    if x == 0.0:
        return 1.0
    return float(f"{x * (10.0 if abs(x) < 1e-3 else 2.0):.12g}")


def _literal(node: ast.AST) -> int | float | None:
    """The value of a number literal, negative ones (``-1``, a unary minus on a constant) too."""
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return node.value
    if (
        isinstance(node, ast.UnaryOp)
        and isinstance(node.op, ast.USub)
        and isinstance(node.operand, ast.Constant)
        and type(node.operand.value) in (int, float)
    ):
        return -node.operand.value
    return None


def _candidates(node: ast.AST) -> Iterator[tuple[str, ast.AST]]:
    """(operator name, replacement node) for each mutation of ``node`` itself."""
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOP_SWAP:
        yield "binop", ast.BinOp(node.left, _BINOP_SWAP[type(node.op)](), node.right)
    elif isinstance(node, ast.Compare):
        for i, op in enumerate(node.ops):
            if type(op) in _CMP_SWAP:
                ops = list(node.ops)
                ops[i] = _CMP_SWAP[type(op)]()
                yield "compare", ast.Compare(node.left, ops, node.comparators)
    elif isinstance(node, ast.BoolOp):
        yield (
            "boolop",
            ast.BoolOp(ast.Or() if isinstance(node.op, ast.And) else ast.And(), node.values),
        )
    elif (value := _literal(node)) is not None:
        yield "constant", ast.Constant(_number_mutation(value))
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.Not):
        yield "unary", node.operand
    elif isinstance(node, ast.Constant) and isinstance(node.value, bool):
        yield "constant", ast.Constant(not node.value)
    elif isinstance(node, ast.Attribute) and node.attr in _NAME_SWAP:
        yield "function", ast.Attribute(node.value, _NAME_SWAP[node.attr], node.ctx)
    elif isinstance(node, ast.Call) and len(node.args) == 1 and not node.keywords:
        f = node.func
        is_abs = (isinstance(f, ast.Name) and f.id == "abs") or (
            isinstance(f, ast.Attribute) and f.attr in ("abs", "absolute")
        )
        if is_abs:
            yield "abs", node.args[0]


def find_mutants(path: str, root: Path = REPO) -> list[Mutant]:
    """Every mutant of the module at ``path`` (relative to ``root``), in source order."""
    source = (root / path).read_text()
    tree = ast.parse(source)
    skip = _skipped_nodes(tree)
    out: list[Mutant] = []
    for node in ast.walk(tree):
        if id(node) in skip or not hasattr(node, "end_col_offset"):
            continue
        if isinstance(node, ast.UnaryOp) and _literal(node) is not None:
            skip.add(id(node.operand))  # a negative literal is mutated as one number
        for operator, new in _candidates(node):
            original = ast.get_source_segment(source, node) or ""
            text = ast.unparse(new)
            replacement = text if _is_atom(new) and not text.startswith("-") else f"({text})"
            if " ".join(original.split()) == replacement:
                continue
            out.append(
                Mutant(
                    path,
                    node.lineno,
                    node.col_offset,
                    node.end_lineno or node.lineno,
                    node.end_col_offset or 0,
                    original,
                    replacement,
                    operator,
                )
            )
    out.sort(key=lambda m: (m.line, m.col, m.operator, m.replacement))
    return out


def _is_atom(node: ast.AST) -> bool:
    """Whether ``node`` needs no parentheses when it replaces an expression."""
    return isinstance(node, ast.Constant | ast.Name | ast.Attribute | ast.Call | ast.Subscript)


def sample(mutants: Sequence[Mutant], fraction: float, seed: int) -> list[Mutant]:
    """A seeded sample of ``fraction`` of ``mutants`` (at least one), in source order."""
    if fraction >= 1.0 or not mutants:
        return list(mutants)
    rng = np.random.default_rng(seed)
    k = max(1, round(fraction * len(mutants)))
    keep = np.sort(rng.choice(len(mutants), size=k, replace=False))
    return [mutants[i] for i in keep]
