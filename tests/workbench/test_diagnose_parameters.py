"""shm diagnose, part 3: wrong parameters are candidates (named first, with the value, the shm fit command and
what the records cannot tell apart), two causes at once are found by forward selection, a fit at its range
bound widens or loses its claim, and the acceptance compares what is left with the noise floor."""

from __future__ import annotations

import json

import pytest
from tip_effects_support import TipSpring

from plant import Parameter
from shm_cli.main import main
from workbench.diagnose import diagnose
from workbench.fit import effect_free_parameters, explained
from workbench.fit._candidates import CORE_RANGE_FACTOR, core_range, widen
from workbench.simulation import synth_record, synth_test, truth_model

NOISE = 2e-6
M3 = 1.39e-3


def _record(effects=(), values=None, kind="mbit-b", seed=0, **spec):
    return synth_record(synth_test(kind, **spec), truth_model("table2", list(effects), values or {}),
                        noise={"z3": NOISE}, seed=seed)


def test_cli_mass_change_gets_a_re_estimate_m3_verdict(tmp_path, capsys):
    rec = tmp_path / "m3.csv"
    assert main(["synth", "--test", "sweep", "--duration-s", "6", "--deviation", "m3=0.5", "--seed", "4",
                 "--out", str(rec)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(rec), "--params", "table2", "--json", "--out", str(tmp_path / "d")]) == 0
    cap = capsys.readouterr()
    result = json.loads(cap.out)
    assert result["verdict"] == "wrong_parameter" and result["found"][0] == "m3"
    assert result["winner_kind"] == "parameter"
    assert f"shm fit {rec} --params table2 --free m3" in result["fit_command"]
    msg = result["message"]
    assert msg.startswith("m3 is wrong: 2.085 g instead of 1.39 g (+50 %) — re-estimate it")
    assert "--free m3" in msg and "Identifiability:" in msg
    est = {e["name"]: e["value"] for e in result["ranking"][0]["estimates"]}
    assert est["m3"] == pytest.approx(1.5 * M3, rel=0.01)
    assert result["ranking"][0]["held_rms_sigma"] < 1.2
    # the table shows the kind of every fitted candidate, and which were screened out
    assert "parameter" in cap.err and "screened out" in cap.err


#: the two true effects and the re-estimations that mimic them (the stiffness group and k3 for the stiffening,
#: beta_h and R_ep for the leakage): the same path as the whole library (screening, fits, forward selection with its
#: beam) with one pair composition to compile instead of many (a third effect adds a pair: ~60 s more when cold)
PAIR_CANDIDATES = ("geometric_stiffening", "dielectric_leakage", "stiffness", "k3", "beta_h", "R_ep")


def _check_two_missing(candidates):
    rec = _record(["geometric_stiffening", "dielectric_leakage"], {"kappa_nl": 5e4, "G_leak": 5e-5}, seed=2)
    d = diagnose([rec], "table2", candidates)
    assert d.verdict == "combination", d.message
    assert set(d.found) == {"geometric_stiffening", "dielectric_leakage"}
    assert len(d.steps) >= 2 and d.steps[0].held_rms_sigma > d.winner.held_rms_sigma
    assert d.winner.held_rms_sigma < 1.3
    assert "Two things at once" in d.message
    assert "--add geometric_stiffening --add dielectric_leakage" in d.fit_command


def test_two_missing_effects_are_found_by_forward_selection():
    _check_two_missing(PAIR_CANDIDATES)


@pytest.mark.slow
@pytest.mark.heavy
def test_two_missing_effects_are_found_among_the_whole_library():
    _check_two_missing(None)  # every library effect and re-estimation: many pairs compile cold (make test-slow)


def test_a_range_bound_widens_up_to_the_parameters_own_bounds():
    from plant.effects.root_compliance import RootClampCompliance as RootCompliance

    fp = next(f for f in effect_free_parameters(RootCompliance) if f.name == "clamp_compliance")
    w = widen(fp, True, RootCompliance, fp.upper)
    assert w is not None and w.upper == 0.05 and w.lower == fp.lower and w.log  # its own upper bound
    assert widen(w, True, RootCompliance, w.upper) is None  # nothing beyond its own bound: the claim is lost
    m3 = core_range("m3", M3)
    assert m3.upper == pytest.approx(CORE_RANGE_FACTOR * M3)
    wm = widen(m3, True, None, m3.upper)
    assert wm is not None and wm.upper > m3.upper and wm.lower == m3.lower
    a = core_range("alpha_h", 0.605)
    assert a.upper == 1.0 and widen(a, True, None, 1.0) is None  # α_h cannot pass 1


class _TipSpring(TipSpring):
    name = "tip_spring_truth"
    description = "spring tip to frame"
    parameters = (Parameter("k_tip_t", "N/m", 0.0, 0.0, 100.0, "tip stiffness"),)


class _NarrowTipSpring(TipSpring):
    """The same spring (its rates), but its own bounds stop short of the truth."""

    name = "tip_spring_narrow"
    description = "spring tip to frame, k below 1 N/m"
    parameters = (Parameter("k_tip_n", "N/m", 0.5, 0.0, 1.0, "tip stiffness"),)


def test_a_candidate_at_its_own_bound_loses_its_claim():
    rec = synth_record(synth_test("mbit-b"), truth_model("table2", [_TipSpring], {"k_tip_t": 5.0}),
                       noise={"z3": NOISE}, seed=1)
    d = diagnose([rec], "table2", [_NarrowTipSpring, "thermal_drift"])
    c = next(c for c in d.ranking if c.effect == "tip_spring_narrow")
    assert c.status == "at bound, unreliable" and not c.accepted and "at bound" in c.rejection
    assert d.verdict in ("unexplained", "partial") and "shm discover" in d.message


def test_joint_standard_error_of_correlated_sensitivities():
    import numpy as np

    from workbench.diagnose._identifiability import joint_rel_se

    a = np.array([3.0, 4.0, 0.0])
    assert joint_rel_se(a, np.array([0.0, 0.0, 2.0])) == pytest.approx(1 / 5)  # orthogonal: 1/|a|
    assert joint_rel_se(a, 2 * a) == float("inf")  # the same shape: cannot be told apart at all
    assert joint_rel_se(a, a + np.array([0.0, 0.0, 0.05])) > 10 * joint_rel_se(a, np.array([0.0, 0.0, 2.0]))


def test_acceptance_scales_with_the_noise_floor_not_a_hard_two_sigma():
    assert explained(1.1, 50.0, 2000)
    assert explained(2.05, 200.0, 2000)  # a true effect found exactly, the remainder 0.01 % of the excess
    assert not explained(2.05, 3.0, 2000)  # most of a small excess left: partial
    assert not explained(5.0, 1e4, 2000)  # far from the floor whatever the baseline
    assert explained(1.25, 10.0, 50) and not explained(1.25, 1.3, 5000)


def _check_mass_and_creep(candidates):
    # the mass group explains most of a wrong m3 alone; with creep added, the backward step swaps the group for m3
    rec = _record(["piezo_creep"], {"gamma_creep": 0.05, "tau_creep": 1.0, "m3": 1.3 * M3}, seed=2)
    d = diagnose([rec], "table2", candidates)
    assert d.verdict == "combination", d.message
    assert set(d.found) == {"m3", "piezo_creep"}
    assert d.winner.outcome.values["m3"] == pytest.approx(1.3 * M3, rel=0.02)
    assert d.winner.held_rms_sigma < 1.3
    assert "--add piezo_creep --free m3" in d.fit_command


def test_wrong_mass_plus_missing_creep_is_a_combination():
    # the creep, the mass group and m3 with the stiffness re-estimations that compete with them: one effect (its
    # composition is shipped warm), the same screening, fits, forward and backward steps as the whole library
    _check_mass_and_creep(("piezo_creep", "mass", "m3", "stiffness", "k3"))


@pytest.mark.slow
@pytest.mark.heavy
def test_wrong_mass_plus_missing_creep_is_a_combination_among_the_whole_library():
    _check_mass_and_creep(None)
