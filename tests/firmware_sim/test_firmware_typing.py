"""The firmware is type-checked as strictly as ``mypy --strict`` would (issue 30 point 7): ``pyproject.toml`` holds a
``[[tool.mypy.overrides]]`` section for ``firmware_sim.*`` with every per-module flag ``--strict`` turns on (``strict``
itself is a global-only option), and ``make typecheck`` (run by ``make test``) applies it."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: the per-module flags of ``mypy --strict`` (warn_unused_ignores and warn_redundant_casts are global already)
STRICT_FLAGS = {"disallow_any_generics": True, "disallow_subclassing_any": True, "disallow_untyped_calls": True,
                "disallow_untyped_defs": True, "disallow_incomplete_defs": True, "check_untyped_defs": True,
                "disallow_untyped_decorators": True, "warn_return_any": True, "implicit_reexport": False,
                "strict_equality": True, "extra_checks": True}


def test_firmware_sim_has_every_strict_flag() -> None:
    mypy = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]
    assert "firmware_sim" in mypy["packages"]
    assert mypy["warn_unused_ignores"] and mypy["warn_redundant_casts"]
    sections = [o for o in mypy.get("overrides", []) if "firmware_sim.*" in o["module"]]
    assert sections, "no [[tool.mypy.overrides]] section for firmware_sim.*"
    flags = {k: v for o in sections for k, v in o.items() if k != "module"}
    missing = {k: v for k, v in STRICT_FLAGS.items() if flags.get(k) != v}
    assert not missing, f"firmware_sim.* lacks these strict flags: {missing}"
