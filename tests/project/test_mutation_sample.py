"""A fixed sample of the mutation check (``make mutate``, docs/testing.md) that runs with ``make test``.

Each case plants one of the bugs issue 18 found the old tests let through — a one-line edit of one function of the
pure core, recompiled in that module's namespace — and asserts that the test written for it now fails. The full
check mutates every line; this sample keeps the most important catches from silently rotting.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
import textwrap
import types
from pathlib import Path

import pytest

from drivers import framing, modbus_registers
from firmware_sim import power_manager, regimes


def load_room_tests(room: str, name: str) -> types.ModuleType:
    """The test module ``tests/<room>/<name>.py`` under its own name, as pytest imports it: the one pytest collected
    when it did, else imported from its file here (and kept in ``sys.modules``, where pytest then finds it)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, Path(__file__).parents[1] / room / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


framing_tests = load_room_tests("drivers", "test_framing_properties")
registers_tests = load_room_tests("drivers", "test_registers_properties")
power_tests = load_room_tests("firmware_sim", "test_power_mc_dc")
regimes_tests = load_room_tests("firmware_sim", "test_regimes_mc_dc")


def plant(monkeypatch, module: types.ModuleType, func: str, old: str, new: str, *users: types.ModuleType) -> None:
    """Replace ``old`` by ``new`` in ``module.func`` (exactly once) and install the result in the module and in
    the test modules that imported the function by name."""
    fn = getattr(module, func)
    src = textwrap.dedent(inspect.getsource(fn))
    assert src.count(old) == 1, f"the planted bug no longer matches {module.__name__}.{func}: {old!r}"
    ns = dict(fn.__globals__)
    exec(compile(src.replace(old, new), inspect.getsourcefile(fn), "exec"), ns)
    for target in (module, *users):
        if hasattr(target, func):
            monkeypatch.setattr(target, func, ns[func])


def test_overruns_that_never_accumulate_are_caught(monkeypatch):
    plant(monkeypatch, regimes, "step_full", "overruns = min(state.overruns + 1, timers.overrun) if inputs.overrun",
          "overruns = 0 if inputs.overrun")
    with pytest.raises(AssertionError):
        regimes_tests.test_five_consecutive_overruns_go_safe(regimes.Regime.STANDBY_HARVEST)


def test_latching_only_the_first_safe_cause_is_caught(monkeypatch):
    plant(monkeypatch, regimes, "step_full", "safe_causes = tuple(c.value for c in (causes or [fired.trigger]))",
          "safe_causes = (fired.trigger.value,)")
    with pytest.raises(AssertionError):
        regimes_tests.test_every_simultaneous_cause_is_latched(regimes.Regime.MAINTENANCE)


def test_brownout_counted_in_total_instead_of_consecutive_is_caught(monkeypatch):
    plant(monkeypatch, power_manager, "power_step",
          "    st = state if state.below_run == 0 else state._replace(below_run=0)\n    return st, (_OK",
          "    st = state\n    return st, (_OK", power_tests)
    with pytest.raises(AssertionError):
        power_tests.test_below_run_must_be_consecutive()


def test_dropping_the_largest_legal_frame_is_caught(monkeypatch):
    plant(monkeypatch, framing.FrameDecoder, "_drain", "if length > MAX_PAYLOAD:", "if length >= MAX_PAYLOAD:")
    with pytest.raises(AssertionError):
        framing_tests.test_the_largest_legal_payload_is_accepted_and_one_more_is_not()


def test_refusing_a_set_point_exactly_at_the_limit_is_caught(monkeypatch):
    plant(monkeypatch, modbus_registers, "check_holding_write", "(hi is not None and v > hi)",
          "(hi is not None and v >= hi)", registers_tests)
    with pytest.raises(AssertionError):
        registers_tests.test_set_points_exactly_at_a_table1_limit_are_accepted("v_ch1", -500.0, 1500.0)
