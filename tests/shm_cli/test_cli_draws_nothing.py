"""The CLI parses, calls and prints (issue 13): no figure or HTML code in ``shm_cli`` — figures and pages live with
their owners (``reporting``, the workbench, the studies)."""

from __future__ import annotations

from pathlib import Path

import pytest

CLI = Path(__file__).resolve().parents[2] / "shm_cli"
#: what drawing or page-writing code looks like
MARKERS = ("matplotlib", "savefig", "subplots(", "base64", "<html", "<table", "<img")


@pytest.mark.parametrize("module", sorted(p.name for p in CLI.glob("*.py")))
def test_no_figure_or_html_code_in_the_cli(module: str) -> None:
    text = (CLI / module).read_text(encoding="utf-8")
    found = [m for m in MARKERS if m in text]
    assert not found, f"shm_cli/{module} draws or writes HTML ({', '.join(found)}): move it to its owner's module"
