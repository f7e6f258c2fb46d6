"""The slow-test list (``tests/slow_tests.py``) names tests that exist: a renamed or removed test must not leave a
stale entry behind while its new name silently joins ``make test-fast``."""

from __future__ import annotations

import ast
from pathlib import Path

from slow_tests import SLOW_TESTS

TESTS = Path(__file__).resolve().parents[1]


def _test_names(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.name for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name.startswith("test")}


def test_every_slow_entry_names_an_existing_test() -> None:
    missing = []
    for entry in sorted(SLOW_TESTS):
        file, _, name = entry.partition("::")
        path = next(TESTS.rglob(file), TESTS / file)
        if not name or not path.is_file() or name not in _test_names(path):
            missing.append(entry)
    assert not missing, f"tests/slow_tests.py names tests that do not exist: {missing}"


def test_the_list_marks_tests_slow_at_collection(request) -> None:
    # this file is fast; a listed test collected in the same session would carry the marker (checked by the hook's
    # key: file name :: function name)
    assert "test_slow_tests.py::test_the_list_marks_tests_slow_at_collection" not in SLOW_TESTS
    assert request.node.get_closest_marker("slow") is None
