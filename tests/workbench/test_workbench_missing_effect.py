"""End to end on simulated records: a correct model passes; a missing effect is flagged by the residual tests and
localised (in time, by regime, in frequency, against the drive). The hidden effects are test-only effects defined
through the plant's effect seam (tests/workbench_hidden_effects.py)."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.compare import CompareOptions, compare
from workbench.simulation import model_for, synth_record, synth_test, truth_model

CUBIC = "workbench_hidden_effects:CubicTipStiffening"
OFFSET = "workbench_hidden_effects:LaserOffset"


def _compare(kind: str, effect: str | None, seed: int, add: tuple[str, ...] = (), level: float = 0.01):
    effects = [effect] if effect else []
    rec = synth_record(synth_test(kind), truth_model("table2", effects=effects), seed=seed, effects=effects)
    return compare(model_for(rec, "table2", effects=add), rec, CompareOptions(level=level, predict=False))


@pytest.mark.parametrize(("kind", "seed"), [("mbit-a", 11), ("mbit-b", 12), ("mbit-b", 13)])
def test_truth_equals_model_plus_white_noise_passes(kind: str, seed: int) -> None:
    cmp = _compare(kind, None, seed, level=1e-4)  # a tight level: any structure from the pipeline would show
    rt = cmp.tests["z3"]
    assert rt.adequate, [(t.key, t.p_value) for t in rt.tests]
    assert cmp.localisation["z3"].windows == [] and cmp.verdicts() == {"z3": "adequate"}
    assert cmp.metrics["z3"].fit_pct > 99.5


def test_missing_cubic_stiffening_mbit_a() -> None:
    cmp = _compare("mbit-a", CUBIC, 3)
    rt, loc = cmp.tests["z3"], cmp.localisation["z3"]
    failed = {t.key for t in rt.failed}
    assert cmp.verdicts()["z3"] == "fails"
    assert {"ee", "ue", "u2e2"} <= failed  # structure, linear share, and amplitude-dependent error
    assert loc.windows and loc.frac_flagged > 0.5
    assert loc.amp_rate is not None and loc.amp_rate.amp_corr > 0.5  # |error| grows with |drive|
    # the error sits at the drive frequency and its low harmonics, not at the modes
    assert loc.bands[0].f_hi_Hz < 1.0
    text = " ".join(cmp.findings["z3"])
    assert "grows with |va|" in text and "φu²'e²(τ) fails" in text


def test_missing_cubic_stiffening_mbit_b_is_localised_in_the_transient() -> None:
    cmp = _compare("mbit-b", CUBIC, 3)
    loc = cmp.localisation["z3"]
    assert cmp.verdicts()["z3"] == "fails" and "ee" in {t.key for t in cmp.tests["z3"].failed}
    top = max(loc.regimes, key=lambda r: r.share_sq_error)
    assert top.label == "transient (step up)" and top.share_sq_error > 0.6
    assert loc.windows[0].regime.startswith("transient")
    # the oscillating part of the error is carried by the band of the first bending mode
    modal = [b for b in loc.bands if b.f_hi_Hz > 0]
    assert modal and "mode 1" in modal[0].near


def test_adding_the_missing_effect_makes_the_model_adequate() -> None:
    cmp = _compare("mbit-b", CUBIC, 3, add=(CUBIC,), level=1e-4)
    assert cmp.verdicts()["z3"] == "adequate" and cmp.metrics["z3"].fit_pct > 99.5


def test_missing_sensor_offset_is_a_bias_only() -> None:
    cmp = _compare("mbit-a", OFFSET, 4)
    rt, loc = cmp.tests["z3"], cmp.localisation["z3"]
    assert {t.key for t in rt.failed} == {"bias"}
    assert loc.bands[0].f_hi_Hz == 0.0 and loc.bands[0].share > 0.95
    assert np.isclose(cmp.metrics["z3"].mean_error, 50e-6, rtol=0.05)
    assert any("constant offset" in f for f in cmp.findings["z3"])
