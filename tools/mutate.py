"""Mutation testing of the grasp core, the S_G LP, vision edges and scene geometry (issue 14).

    python -m tools.mutate                     # every mutant, 2 jobs
    python -m tools.mutate --fraction 0.3      # a seeded 30 % sample
    python -m tools.mutate --module score --list

Each mutant is one small change to one module's source: an arithmetic or comparison operator
swapped, ``and``/``or`` exchanged, a unary minus or ``not`` dropped, a number changed (an integer
by one, a float by a factor of 2, a tolerance below 1e-3 by 10), a numpy reduction or function
swapped for its twin (max/min, argmin/argmax, any/all, cos/sin, sum/mean) or ``abs`` dropped.
Mutants are found on the syntax tree (docstrings, strings, f-strings, annotations, decorators
and imports are left alone) and written into a private copy of the repository, one worker copy
per job. The test files that cover the module run against the mutant with ``pytest -x``: a
failure (or a crash or time-out) kills the mutant; a mutant that passes every test survives.

Every mutant runs by default; ``--fraction`` takes a seeded sample for a quicker look (the same
seed gives the same mutants). Mutants known to be equivalent (no test can tell them from the
original) are listed with the reason in :mod:`tools.equivalent`: they count as survivors but
are not run again unless ``--check-equivalent`` is given (which reports any that a test now
kills). Exit status 0 when the share of surviving mutants is at most ``--max-survival``
(default 10 %), 1 otherwise, 2 for bad arguments or when the unmutated tests fail.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from tools.equivalent import reason_for

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Target:
    """A module under mutation and the test files that cover it (fastest first)."""

    name: str
    path: str
    tests: tuple[str, ...]


TARGETS: tuple[Target, ...] = (
    Target(
        "wrench",
        "controllers/grasp/wrench.py",
        ("tests/test_wrench.py", "tests/test_composition.py", "tests/test_trials.py"),
    ),
    Target(
        "composition",
        "controllers/grasp/composition.py",
        ("tests/test_composition.py", "tests/test_trials.py"),
    ),
    Target(
        "trials",
        "controllers/grasp/trials.py",
        ("tests/test_trials.py", "tests/test_wrench.py", "tests/test_preimaging.py"),
    ),
    Target(
        "polygon",
        "controllers/grasp/polygon.py",
        (
            "tests/test_polygon.py",
            "tests/test_wrench.py",
            "tests/test_score.py",
            "tests/test_trials.py",
            "tests/test_parser_fuzz.py",
        ),
    ),
    Target("score", "controllers/grasp/score.py", ("tests/test_score.py", "tests/test_trials.py")),
    Target("edges", "vision/edges.py", ("tests/test_vision_edges.py", "tests/test_vision.py")),
    Target("geometry", "hand_sim/geometry.py", ("tests/test_scene.py",)),
)

#: Default share of each module's mutants that a run takes.
DEFAULT_FRACTION = 1.0
#: A mutant's tests may take this many times the unmutated run (plus a floor) before it counts
#: as killed by a time-out (an endless loop).
TIMEOUT_FACTOR = 4.0
TIMEOUT_FLOOR_S = 30.0

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
    return isinstance(node, ast.Constant | ast.Name | ast.Attribute | ast.Call | ast.Subscript)


def sample(mutants: Sequence[Mutant], fraction: float, seed: int) -> list[Mutant]:
    """A seeded sample of ``fraction`` of ``mutants`` (at least one), in source order."""
    if fraction >= 1.0 or not mutants:
        return list(mutants)
    rng = np.random.default_rng(seed)
    k = max(1, round(fraction * len(mutants)))
    keep = np.sort(rng.choice(len(mutants), size=k, replace=False))
    return [mutants[i] for i in keep]


@dataclass(frozen=True)
class Outcome:
    """What the tests made of one mutant."""

    mutant: Mutant
    status: str  #: "killed", "survived", "timeout" (counts as killed) or "error"
    detail: str  #: the first failing test, or the reason
    seconds: float
    equivalent: str = ""  #: why it is equivalent, when tools.equivalent lists it


def make_copy(dest: Path) -> Path:
    """A private copy of the repository (sources, tests, models, scenes) to mutate."""
    ignore = shutil.ignore_patterns(".git", ".venv", "runs", "__pycache__", "*.pyc", ".ruff_cache")
    shutil.copytree(REPO, dest, ignore=ignore)
    return dest


def run_tests(copy: Path, tests: Sequence[str], timeout: float) -> tuple[str, str, float]:
    """Run ``tests`` in ``copy`` with pytest -x: (status, detail, seconds)."""
    env = dict(
        os.environ, PYTHONDONTWRITEBYTECODE="1", MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl")
    )
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-x",
        "-q",
        "-p",
        "no:cacheprovider",
        "-p",
        "no:randomly",
    ]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [*cmd, *tests], cwd=copy, env=env, capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return "timeout", f"no result after {timeout:.0f} s", time.perf_counter() - t0
    seconds = time.perf_counter() - t0
    if proc.returncode == 0:
        return "survived", "", seconds
    if proc.returncode in (1, 2, 3):
        failed = [ln for ln in proc.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))]
        detail = failed[0].split(" - ")[0] if failed else f"pytest exit {proc.returncode}"
        return "killed", detail, seconds
    return "error", f"pytest exit {proc.returncode}: {proc.stdout[-300:]}", seconds


def evaluate(
    mutant: Mutant, copy: Path, tests: Sequence[str], original: str, timeout: float
) -> Outcome:
    """Write ``mutant`` into ``copy``, run the tests, restore the module."""
    target = copy / mutant.path
    mutated = mutant.apply(original)
    try:
        compile(mutated, mutant.path, "exec")
    except SyntaxError as e:  # a mutation the grammar refuses: not a mutant
        return Outcome(mutant, "error", f"syntax error: {e}", 0.0)
    target.write_text(mutated)
    try:
        status, detail, seconds = run_tests(copy, tests, timeout)
    finally:
        target.write_text(original)
    return Outcome(mutant, status, detail, seconds, equivalent_reason(mutant, original))


def equivalent_reason(mutant: Mutant, source: str) -> str:
    """Why ``mutant`` of ``source`` is equivalent, or "" when it is not listed."""
    line = source.splitlines()[mutant.line - 1]
    return reason_for(mutant.path, line, mutant.col, mutant.original, mutant.replacement)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.mutate", description=__doc__.splitlines()[0])
    names = [t.name for t in TARGETS]
    p.add_argument("--module", action="append", choices=names, help="only these (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="sample seed (default 0)")
    p.add_argument("--fraction", type=float, default=DEFAULT_FRACTION, help="share sampled")
    p.add_argument(
        "--check-equivalent", action="store_true", help="run the listed equivalent mutants too"
    )
    p.add_argument("--jobs", type=int, default=2, help="parallel workers (default 2)")
    p.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    p.add_argument("--match", help="only mutants whose label contains this text")
    p.add_argument("--rerun", type=Path, help="only the survivors of an earlier --json file")
    p.add_argument("--json", type=Path, help="write every outcome to this file")
    p.add_argument("--max-survival", type=float, default=0.10, help="exit 1 above (default 0.1)")
    a = p.parse_args(argv)
    if not 0.0 < a.fraction <= 1.0:
        print(f"tools.mutate: --fraction must be in (0, 1], got {a.fraction}", file=sys.stderr)
        return 2
    if a.jobs < 1:
        print(f"tools.mutate: --jobs must be >= 1, got {a.jobs}", file=sys.stderr)
        return 2
    targets = [t for t in TARGETS if not a.module or t.name in a.module]
    fraction = 1.0 if a.rerun else a.fraction
    wanted: set[str] | None = None
    if a.rerun is not None:
        try:
            earlier = json.loads(a.rerun.read_text())
        except (OSError, ValueError) as e:
            print(f"tools.mutate: cannot read --rerun {a.rerun}: {e}", file=sys.stderr)
            return 2
        wanted = {Mutant(**o["mutant"]).label for o in earlier if o["status"] == "survived"}
    plan: list[tuple[Target, Mutant]] = []
    for i, t in enumerate(targets):
        found = find_mutants(t.path)
        chosen = [
            m
            for m in sample(found, fraction, a.seed + 1000 * i)
            if (wanted is None or m.label in wanted) and (not a.match or a.match in m.label)
        ]
        print(f"{t.name:12} {t.path:36} {len(found):4d} mutants, {len(chosen):4d} chosen")
        plan += [(t, m) for m in chosen]
    if a.list:
        for _, m in plan:
            print(m.label)
        return 0
    return _run(plan, targets, a.jobs, a.json, a.max_survival, a.check_equivalent)


def _run(
    plan: list[tuple[Target, Mutant]],
    targets: Sequence[Target],
    jobs: int,
    json_path: Path | None,
    max_survival: float,
    check_equivalent: bool,
) -> int:
    t_start = time.perf_counter()
    sources = {t.path: (REPO / t.path).read_text() for t in targets}
    listed: list[Outcome] = []
    if not check_equivalent:  # known survivors: counted, not run again
        for t, m in plan:
            reason = equivalent_reason(m, sources[t.path])
            if reason:
                listed.append(Outcome(m, "survived", "listed equivalent, not run", 0.0, reason))
        skip = {id(o.mutant) for o in listed}
        plan = [(t, m) for t, m in plan if id(m) not in skip]
    with tempfile.TemporaryDirectory(prefix="graspsim-mutate-") as tmp:
        copies = [make_copy(Path(tmp) / f"w{k}") for k in range(jobs)]
        baseline: dict[str, float] = {}
        for t in targets:  # the unmutated tests must pass, and set each module's time-out
            status, detail, seconds = run_tests(copies[0], t.tests, 3600.0)
            if status != "survived":
                print(
                    f"tools.mutate: the unmutated tests of {t.name} fail ({detail}); "
                    "fix them first",
                    file=sys.stderr,
                )
                return 2
            baseline[t.path] = seconds
            print(f"baseline {t.name}: tests pass in {seconds:.1f} s")
        free = list(copies)
        outcomes: list[Outcome] = list(listed)
        print(f"{len(listed)} listed equivalent mutants counted as survivors, not run")

        def one(item: tuple[Target, Mutant]) -> Outcome:
            t, m = item
            copy = free.pop()
            try:
                timeout = TIMEOUT_FLOOR_S + TIMEOUT_FACTOR * baseline[t.path]
                return evaluate(m, copy, t.tests, sources[t.path], timeout)
            finally:
                free.append(copy)

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            for k, out in enumerate(pool.map(one, plan), 1):
                outcomes.append(out)
                tag = out.status.upper() + (" (equivalent)" if out.equivalent else "")
                if out.equivalent and out.status != "survived":
                    tag = out.status.upper() + " (listed equivalent: remove it)"
                print(f"[{k:3d}/{len(plan)}] {tag:22} {out.mutant.label}  {out.detail}", flush=True)
    print(_summary(outcomes, targets, time.perf_counter() - t_start))
    if json_path is not None:
        json_path.write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    run = [o for o in outcomes if o.status != "error"]
    rate = sum(o.status == "survived" for o in run) / max(1, len(run))
    return 0 if rate <= max_survival else 1


def _summary(outcomes: Sequence[Outcome], targets: Sequence[Target], seconds: float) -> str:
    lines = [
        "",
        f"{'module':12} {'mutants':>7} {'killed':>7} {'survived':>8} {'equiv.':>6} {'rate':>7}",
    ]
    totals = np.zeros(4, int)
    for t in targets:
        rs = [o for o in outcomes if o.mutant.path == t.path and o.status != "error"]
        killed = sum(o.status in ("killed", "timeout") for o in rs)
        surv = [o for o in rs if o.status == "survived"]
        eq = sum(bool(o.equivalent) for o in surv)
        totals += (len(rs), killed, len(surv), eq)
        rate = 100.0 * len(surv) / max(1, len(rs))
        lines.append(f"{t.name:12} {len(rs):7d} {killed:7d} {len(surv):8d} {eq:6d} {rate:6.1f}%")
    n, killed, surv, eq = (int(x) for x in totals)
    lines.append(
        f"{'all':12} {n:7d} {killed:7d} {surv:8d} {eq:6d} {100.0 * surv / max(1, n):6.1f}%"
    )
    lines.append(
        f"survival {100.0 * surv / max(1, n):.1f} % ({surv}/{n}); without the {eq} equivalent "
        f"mutants {100.0 * (surv - eq) / max(1, n - eq):.1f} %; {seconds / 60:.1f} min"
    )
    errors = [o for o in outcomes if o.status == "error"]
    if errors:
        lines.append(f"{len(errors)} mutants not run: " + "; ".join(o.detail for o in errors[:3]))
    survivors = [o for o in outcomes if o.status == "survived"]
    if survivors:
        lines.append("survivors:")
        for o in survivors:
            note = f"  equivalent: {o.equivalent}" if o.equivalent else ""
            lines.append(f"  {o.mutant.label}{note}")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
