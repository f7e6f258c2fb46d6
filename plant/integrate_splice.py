"""Splice a helper's body into its caller's source: the one piece of generation the integrators need.

numba's ``inline="always"`` binds every array argument of an inlined function to a new variable, which costs a
reference-count increment and decrement per array per call. For the member-by-member integrator's step
(:func:`plant.integrate_scalar.attempt`, :func:`plant.integrate_scalar.dense_outputs`: fifteen arrays, called once
per attempted step) that was ~20 % of a step. So :func:`spliced_source` writes the helper's body in place of the
call, in the caller's source, before numba sees it: the helpers stay ordinary functions that ruff, mypy and a
reader see, and the compiled step is the one written out by hand.

The rules are narrow and checked: the call is a statement of its own (``a, b = helper(...)``, ``j = helper(...)``
or ``helper(...)``) whose arguments are plain names; the helper ends in its only ``return`` (or has none); its
parameters become the argument names (a parameter it assigns to starts as a copy) and its own local names get the
prefix ``<helper>_`` (so they cannot clash with the caller's).
"""

from __future__ import annotations

import ast
import copy
import inspect
import textwrap
from collections.abc import Callable, Sequence
from typing import Any


class SpliceError(ValueError):
    """A call or a helper outside the rules of :func:`spliced_source`."""


def _function_def(fn: Callable[..., Any]) -> ast.FunctionDef:
    node = ast.parse(textwrap.dedent(inspect.getsource(fn))).body[0]
    if not isinstance(node, ast.FunctionDef):
        raise SpliceError(f"{fn.__name__} is not a plain function")
    return node


def _body_without_docstring(f: ast.FunctionDef) -> list[ast.stmt]:
    body = list(f.body)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]
    return body


class _Rename(ast.NodeTransformer):
    def __init__(self, names: dict[str, str]) -> None:
        self.names = names

    def visit_Name(self, node: ast.Name) -> ast.Name:
        return ast.copy_location(ast.Name(self.names.get(node.id, node.id), node.ctx), node)


def _inlined(helper: ast.FunctionDef, call: ast.Call, targets: list[ast.expr]) -> list[ast.stmt]:
    """The helper's statements for ``targets = call`` (``targets`` empty: a bare call)."""
    params = [a.arg for a in helper.args.args]
    if call.keywords or len(call.args) != len(params) or not all(isinstance(a, ast.Name) for a in call.args):
        raise SpliceError(f"call of {helper.name}: arguments must be {len(params)} plain names, by position")
    body = copy.deepcopy(_body_without_docstring(helper))
    returns = [n for n in ast.walk(helper) if isinstance(n, ast.Return)]
    if len(returns) > 1 or (returns and not isinstance(body[-1], ast.Return)):
        raise SpliceError(f"{helper.name}: only one return, as its last statement")
    if any(isinstance(n, (ast.FunctionDef, ast.Lambda, ast.Global, ast.Nonlocal)) for n in ast.walk(helper)
           if n is not helper):
        raise SpliceError(f"{helper.name}: no nested functions, global or nonlocal")
    local = {n.id for n in ast.walk(helper) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
    names = {p: a.id for p, a in zip(params, call.args, strict=True) if isinstance(a, ast.Name)}
    names |= {n: f"{helper.name}_{n}" for n in local}  # an assigned parameter is a local copy
    copies: list[ast.stmt] = [ast.Assign(targets=[ast.Name(names[p], ast.Store())], value=ast.Name(a, ast.Load()))
                              for p, a in zip(params, (c.id for c in call.args if isinstance(c, ast.Name)),
                                              strict=True) if p in local]
    renamed = copies + [_Rename(names).visit(s) for s in body]
    if returns:
        last = renamed.pop()
        assert isinstance(last, ast.Return)
        if targets and last.value is not None:
            renamed.append(ast.Assign(targets=targets, value=last.value))
        elif targets:
            raise SpliceError(f"{helper.name} returns nothing but its result is assigned")
    elif targets:
        raise SpliceError(f"{helper.name} returns nothing but its result is assigned")
    return renamed


class _Splice(ast.NodeTransformer):
    def __init__(self, helpers: dict[str, ast.FunctionDef]) -> None:
        self.helpers = helpers
        self.spliced: set[str] = set()

    def _call_of_helper(self, value: ast.expr | None) -> ast.Call | None:
        if isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and value.func.id in self.helpers:
            return value
        return None

    def generic_visit(self, node: ast.AST) -> ast.AST:
        for field in ("body", "orelse"):
            stmts = getattr(node, field, None)
            if isinstance(stmts, list) and stmts and isinstance(stmts[0], ast.stmt):
                setattr(node, field, [out for s in stmts for out in self._statement(s)])
        return super().generic_visit(node)

    def _statement(self, stmt: ast.stmt) -> list[ast.stmt]:
        if isinstance(stmt, ast.Assign) and len(stmt.targets) == 1:
            call, targets = self._call_of_helper(stmt.value), stmt.targets
        elif isinstance(stmt, ast.Expr):
            call, targets = self._call_of_helper(stmt.value), []
        else:
            call, targets = None, []
        if call is None:
            return [stmt]
        assert isinstance(call.func, ast.Name)
        self.spliced.add(call.func.id)
        return _inlined(self.helpers[call.func.id], call, targets)


def spliced_source(caller: Callable[..., Any], helpers: Sequence[Callable[..., Any]]) -> str:
    """The source of ``caller`` with every call of a function in ``helpers`` replaced by that function's body (see
    the module docstring); comments are not kept. Raises :class:`SpliceError` when a helper is never called as a
    statement of its own, or breaks a rule."""
    tree = _function_def(caller)
    splice = _Splice({h.__name__: _function_def(h) for h in helpers})
    tree = splice.visit(tree)
    missing = {h.__name__ for h in helpers} - splice.spliced
    if missing:
        raise SpliceError(f"{caller.__name__} never calls {sorted(missing)} as a statement of its own")
    ast.fix_missing_locations(tree)
    return ast.unparse(tree) + "\n"
