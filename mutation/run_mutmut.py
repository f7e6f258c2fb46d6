"""``mutmut`` with each mutant's tests run fastest first (by the durations mutmut measured in its coverage pass).

mutmut hands pytest a mutant's covering tests in set order; pytest stops at the first failure (``-x``), so running
the fast, pointed tests (MC/DC, boundary cases) before the long hypothesis runs makes most kills take a second.
Usage (from a work directory): ``python mutation/run_mutmut.py run --max-children 2``.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable

from mutmut.runners import harness
from mutmut.state import state

_regular_run = harness.PytestRunner._pytest_args_regular_run


def _fastest_first(self: harness.PytestRunner, tests: Iterable[str]) -> list[str]:
    durations = state().duration_by_test
    return _regular_run(self, sorted(tests, key=lambda t: (durations.get(t, 0.0), t)))


harness.PytestRunner._pytest_args_regular_run = _fastest_first

if __name__ == "__main__":
    from mutmut.__main__ import cli

    sys.exit(cli())
