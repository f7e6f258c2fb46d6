"""Lane form of effect hooks: one hook body run for ``LANES`` batch members at once, for SIMD.

An effect hook is written for one trajectory: it reads and writes ``x[i]``, ``p[i]``, ``bus[i]``, ``dx[i]`` (``y[i]``
for the output hook). :func:`lane_hook_source` rewrites it, at the syntax level, into a function of one flat work
array ``W`` holding every array of ``LANES`` members row by row (row ``r``, lane ``l`` at ``W[r * LANES + l]``):
``x[e]`` becomes ``W[(ROW_x + e) * LANES + _lane_]`` inside a loop over the lanes. Every offset and ``LANES`` are
compile-time constants and all data live in one array, so LLVM sees that the accesses do not overlap and
vectorises the lane loop (the loop over members), which a per-member ``rhs`` can never be.

The rewrite is deliberately narrow. A hook that uses one of its arrays other than as ``array[index]`` (a slice,
``x.shape``, passing ``x`` to a helper), returns early, defines functions or closes over variables is reported as
:class:`LaneFormUnsupported`; its composition then integrates member by member as before (nothing else changes).
Names the hook takes from its module (constants such as ``X_Q``, helpers, ``np``) are renamed
``_G<k>_<name>`` and bound from the hook's module in the generated source.
"""

from __future__ import annotations

import ast
import builtins
import inspect
import textwrap
from collections.abc import Callable
from typing import Any

#: the lane loop's variable and the work array's name in generated hooks (a hook using them is not rewritten)
LANE_VAR = "_lane_"
WORK = "W"
#: array argument position (1..4 after ``t``) -> row block name (``ROW_<name>`` in the generated module)
PHASE_ROLES = ("x", "p", "bus", "dx")
OUTPUT_ROLES = ("x", "p", "bus", "y")


class LaneFormUnsupported(ValueError):
    """A hook cannot be rewritten in lane form (the reason names what it does)."""


def lane_hook_source(fn: Callable[..., Any], new_name: str, tag: str, roles: tuple[str, ...] = PHASE_ROLES,
                     ) -> tuple[str, dict[str, str]]:
    """Source of the lane form of hook ``fn`` named ``new_name``, and the module names it needs:
    ``{"_G<tag>_<name>": "<name>"}`` (bind each from ``fn``'s module). Its signature is ``(t, W, *rest)``, where
    ``rest`` are the hook's arguments after its four arrays (slot tables or offsets). Raises
    :class:`LaneFormUnsupported`."""
    if getattr(fn, "__closure__", None):
        raise LaneFormUnsupported("the hook closes over variables")
    try:
        src = textwrap.dedent(inspect.getsource(fn))
    except (OSError, TypeError) as exc:
        raise LaneFormUnsupported(f"no source ({exc})") from exc
    tree = ast.parse(src)
    f = tree.body[0]
    if not isinstance(f, ast.FunctionDef):
        raise LaneFormUnsupported("not a plain function")
    if f.args.vararg or f.args.kwarg or f.args.kwonlyargs or f.args.posonlyargs or f.args.defaults:
        raise LaneFormUnsupported("the hook's signature is not plain positional")
    params = [a.arg for a in f.args.args]
    if len(params) < 5:
        raise LaneFormUnsupported("the hook takes fewer than five arguments")
    arrays = dict(zip(params[1:5], roles, strict=True))
    local = set(params)
    for node in ast.walk(f):
        if node is not f and isinstance(node, (ast.Return, ast.Lambda, ast.FunctionDef, ast.AsyncFunctionDef,
                                               ast.ClassDef, ast.Yield, ast.YieldFrom, ast.Global,
                                               ast.Nonlocal, ast.Await, ast.With, ast.Try)):
            raise LaneFormUnsupported(f"the hook uses {type(node).__name__}")
        if isinstance(node, ast.Name):
            if node.id in (LANE_VAR, WORK):
                raise LaneFormUnsupported(f"the hook uses the name {node.id!r}")
            if isinstance(node.ctx, (ast.Store, ast.Del)):
                local.add(node.id)
    module_globals = getattr(fn, "__globals__", {})
    needed: dict[str, str] = {}

    class _Rewrite(ast.NodeTransformer):
        def visit_Subscript(self, node: ast.Subscript) -> ast.AST:
            if isinstance(node.value, ast.Name) and node.value.id in arrays:
                if isinstance(node.slice, (ast.Slice, ast.Tuple)):
                    raise LaneFormUnsupported(f"the hook slices {node.value.id!r}")
                row = ast.BinOp(ast.Name(f"ROW_{arrays[node.value.id]}", ast.Load()), ast.Add(),
                                self.visit(node.slice))
                index = ast.BinOp(ast.BinOp(row, ast.Mult(), ast.Name("LANES", ast.Load())), ast.Add(),
                                  ast.Name(LANE_VAR, ast.Load()))
                return ast.copy_location(ast.Subscript(ast.Name(WORK, ast.Load()), index, node.ctx), node)
            return self.generic_visit(node)

        def visit_Name(self, node: ast.Name) -> ast.AST:
            if node.id in arrays:
                raise LaneFormUnsupported(f"the hook uses the array {node.id!r} other than by index")
            if node.id in local:
                return node
            if node.id in module_globals or not hasattr(builtins, node.id):
                bound = f"_G{tag}_{node.id}"
                needed[bound] = node.id
                return ast.copy_location(ast.Name(bound, node.ctx), node)
            return node

    body = [s for s in f.body if not _is_docstring(s)] or [ast.Pass()]
    uniform = (len(body) == 1 and isinstance(body[0], ast.If)
               and _parameter_only(body[0].test, p_name=params[2], tables=set(params[5:]), local=local))
    f = _Rewrite().visit(f)
    body = [s for s in f.body if not _is_docstring(s)] or [ast.Pass()]
    f.decorator_list = []
    f.returns = None
    f.name = new_name
    f.args.args = [ast.arg(params[0]), ast.arg(WORK)] + [ast.arg(a) for a in params[5:]]
    f.body = _unswitched(body[0]) if uniform and isinstance(body[0], ast.If) else [_lane_loop(body)]
    ast.fix_missing_locations(f)
    return ast.unparse(f), needed


def _lane_loop(body: list[ast.stmt], start: int = 0) -> ast.For:
    args: list[ast.expr] = [ast.Name("LANES", ast.Load())]
    if start:
        args.insert(0, ast.Constant(start))
    return ast.For(target=ast.Name(LANE_VAR, ast.Store()), iter=ast.Call(ast.Name("range", ast.Load()), args, []),
                   body=body, orelse=[])


def _parameter_only(test: ast.expr, p_name: str, tables: set[str], local: set[str]) -> bool:
    """True when ``test`` reads nothing but parameters ``p[...]``, slot tables, constants and module names (so it
    is the same at every step, and usually for every member of a group)."""
    for node in ast.walk(test):
        if isinstance(node, (ast.Call, ast.NamedExpr, ast.Lambda, ast.comprehension)):
            return False
        if isinstance(node, ast.Name) and node.id in local and node.id != p_name and node.id not in tables:
            return False
        if isinstance(node, ast.Subscript) and not (isinstance(node.value, ast.Name) and node.value.id == p_name):
            return False
    return True


def _unswitched(branch: ast.If) -> list[ast.stmt]:
    """Lane form of a hook whose body is one ``if`` on parameters: when the test has the same value for every lane
    (the usual case) only that branch runs, in a lane loop free of the other (a power or a division the other
    branch needs is then not computed for every lane, which if-conversion of a vectorised loop would do)."""
    first = ast.Name("_uniform_test_", ast.Store())
    same = ast.Name("_uniform_", ast.Store())
    differs = ast.If(test=ast.Compare(ast.Call(ast.Name("bool", ast.Load()), [branch.test], []), [ast.NotEq()],
                                      [ast.Name("_uniform_test_", ast.Load())]),
                     body=[ast.Assign([same], ast.Constant(False))], orelse=[])
    return [
        ast.Assign([ast.Name(LANE_VAR, ast.Store())], ast.Constant(0)),
        ast.Assign([first], ast.Call(ast.Name("bool", ast.Load()), [branch.test], [])),
        ast.Assign([same], ast.Constant(True)),
        _lane_loop([differs], start=1),
        ast.If(test=ast.Name("_uniform_", ast.Load()),
               body=[ast.If(test=ast.Name("_uniform_test_", ast.Load()), body=[_lane_loop(branch.body)],
                            orelse=[_lane_loop(branch.orelse)] if branch.orelse else [])],
               orelse=[_lane_loop([branch])]),
    ]


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)
