"""The integrators are code (issue 30 point 3): no Python source in string literals, every name the templates take
from ``plant.integrate_kernel_names`` is bound in a generated kernel module, and the splice of a helper into its
caller follows its rules."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from plant import integrate, integrate_kernel_names, integrate_lanes, integrate_scalar
from plant.compose import generate_source
from plant.integrate_splice import SpliceError, spliced_source

PLANT = Path(integrate.__file__).parent


def _python_in_strings(path: Path) -> list[int]:
    """Lines of string literals in ``path`` that parse as Python holding a function definition."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and "def " in node.value:
            try:
                tree = ast.parse(node.value)
            except SyntaxError:
                continue
            if any(isinstance(n, ast.FunctionDef) for n in ast.walk(tree)):
                lines.append(node.lineno)
    return lines


def test_no_integrator_source_in_string_literals():
    files = sorted(PLANT.glob("integrate*.py"))
    assert len(files) >= 5
    assert {f.name: _python_in_strings(f) for f in files} == {f.name: [] for f in files}


def test_every_kernel_name_the_templates_use_is_bound_in_a_generated_module(table2_model):
    """What the templates import from integrate_kernel_names, a lane composition's kernel module defines itself."""
    source = generate_source(table2_model.effects, *table2_model._offsets, table2_model.n_states, True)
    tree = ast.parse(source)
    defined = {t.id for n in tree.body if isinstance(n, ast.Assign) for t in n.targets if isinstance(t, ast.Name)}
    defined |= {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    used: set[str] = set()
    for module in (integrate_scalar, integrate_lanes):
        for node in ast.parse(Path(module.__file__).read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.module == "plant.integrate_kernel_names":
                used |= {a.name for a in node.names}
    types = {n for n in used if n[0].isupper() and not n.isupper() and not n.startswith("ROW_")}
    assert used - types - defined == set()
    assert {"rhs", "out", "rhs_lanes", "out_lanes", "run_chunk", "run_chunk_stats", "run_lanes"} <= defined
    for name in used - types:  # and the declarations exist (never callable outside a kernel module)
        assert hasattr(integrate_kernel_names, name)
    with pytest.raises(RuntimeError, match=r"bound by plant\.compose"):
        integrate_kernel_names.rhs(0.0, *(integrate_kernel_names.np.zeros(1),) * 5)


def test_the_step_helpers_are_written_into_one_and_nowhere_called():
    """``one`` of the kernel module carries the bodies of ``attempt`` and ``dense_outputs``, under renamed locals;
    the helpers themselves are not in the module (nothing there calls them)."""
    text = spliced_source(integrate_scalar.one, (integrate_scalar.attempt, integrate_scalar.dense_outputs))
    assert "attempt(" not in text and "dense_outputs(" not in text
    assert "attempt_err2" in text and "dense_outputs_j = j" in text
    assert "def attempt(" not in integrate.INTEGRATOR_SOURCE and "def one(" in integrate.INTEGRATOR_SOURCE
    assert text in integrate.INTEGRATOR_SOURCE


def _adds(a, b):
    c = a + b
    return c


def _no_return(a, out):
    out[0] = a


def _two_returns(a):
    if a:
        return 1
    return 2


def _caller(x, y, buf):
    c = 5
    s = _adds(x, y)
    _no_return(c, buf)
    return s + c


def _bad_caller(x):
    return _two_returns(x) + 1


def _caller_of_two_returns(x):
    r = _two_returns(x)
    return r


def test_splice_keeps_the_meaning():
    text = spliced_source(_caller, (_adds, _no_return))
    assert "_adds(" not in text and "_no_return(" not in text
    ns: dict = {}
    exec(text, ns)
    buf = [0]
    assert ns["_caller"](2, 3, buf) == _caller(2, 3, [0]) == 10 and buf == [5]
    with pytest.raises(SpliceError, match="never calls"):
        spliced_source(_bad_caller, (_two_returns,))
    with pytest.raises(SpliceError, match="only one return"):
        spliced_source(_caller_of_two_returns, (_two_returns,))


def test_the_integration_seam_does_not_import_the_model():
    """plant.stepper needs only a ``ComposedModel`` (a protocol), not plant.model: no import circle, not even
    type-only (issue 30)."""
    import grimp

    graph = grimp.build_graph("plant")
    assert graph.find_shortest_chain(importer="plant.stepper", imported="plant.model") is None
    assert "plant.model" not in graph.find_modules_directly_imported_by("plant.stepper")
