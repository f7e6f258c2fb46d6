"""The damage family's wider switches (issue 26 point 3): a section's lost stiffness or damping that grows with the
opening (a crack whose faces part progressively), a section's stiffness switched by the tip's swing (z3), a patch's
coupling switched by the drive over a smooth edge, and one patch's own coupling switched by its section's bending
(partly debonded) — members of the dictionary, said in words, and each emitted file moving the beam exactly as the
same damage written outside the project (``tests/workbench_blind_damage.py``, whose author never read the
dictionary)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.discover import build_dictionary
from workbench.discover._effect_writer import emit_effect_source, parameter_names_for
from workbench.discover._gate_words import describe_damage
from workbench.discover._gates import class_stem, gate_values

SCALES = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 6e-4), ("ddelta", 0.1))
          for i in (1, 2, 3)} | {"vc": 50.0, "va": 100.0, "t": 6.0}
BLIND = Path(__file__).parents[1] / "workbench_blind_damage.py"
BLIND4 = Path(__file__).parents[1] / "workbench_blind_damage_4.py"


def _families(driven: bool = True) -> set[tuple[str, int, str, str]]:
    return {(t.param, t.index, t.form, t.signal) for t in build_dictionary(SCALES, driven=driven)
            if t.placement == "damage"}


def test_the_wider_switches_are_members_for_every_section_and_patch():
    fams = _families()
    for i in range(3):
        n = i + 1
        for side in ("pos", "neg"):
            assert {("k", i, f"on_{side}_grow", f"delta{n}"), ("c", i, f"on_{side}_grow", f"delta{n}"),
                    ("k", i, f"on_{side}", "z3"), ("k", i, f"on_{side}_soft", "z3"),
                    ("d_ep_i", i, f"on_{side}", f"delta{n}"), ("d_ep_i", i, f"on_{side}_soft", f"delta{n}"),
                    ("d_ep_i", i, f"on_{side}_soft", "va")} <= fams
    assert {("d_ep", -1, "on_pos_soft", "va"), ("d_ep", -1, "on_neg_soft", "va")} <= fams
    # an undriven record has no drive: the smooth polarity switch reads the patch voltage instead
    free = _families(driven=False)
    assert ("d_ep", -1, "on_neg_soft", "vc") in free and not any(f[3] == "va" for f in free)


def test_a_growing_gate_rises_with_the_opening_and_saturates():
    d = np.linspace(-2e-3, 2e-3, 401)
    t = np.zeros_like(d)
    assert np.allclose(gate_values("on_neg_grow", d, 1e-3, t, "m"), np.clip(-d / 1e-3, 0.0, 1.0))
    assert np.allclose(gate_values("on_pos_grow", d, 1e-3, t, "m"), np.clip(d / 1e-3, 0.0, 1.0))
    grow = [t for t in build_dictionary(SCALES) if t.form == "on_neg_grow" and t.param == "k"]
    assert [t.shape for t in grow] == pytest.approx([6e-4] * 3) and all(t.shape_range is None for t in grow)


def test_words_say_the_wider_switches_as_an_engineer_would():
    grow = describe_damage("k", 2, "on_neg_grow", "delta3", -0.15, 4e-3)
    assert grow.startswith("a breathing crack in section 3 that opens for δ3 < 0, its lost stiffness growing")
    assert "k3 lower by 15 % once δ3 reaches −4 mm" in grow
    tip = describe_damage("k", 0, "on_neg", "z3", -0.2, 0.0)
    assert tip.startswith("a crack in section 1 opened by the beam's swing: stiffness k1 lower by 20 % while the "
                          "tip is below 0 (z3 < 0)")
    soft_tip = describe_damage("k", 0, "on_neg_soft", "z3", -0.2, 2e-4)
    assert "switching over about ±200 µm of z3" in soft_tip
    drive = describe_damage("d_ep_i", 1, "on_neg_soft", "va", -0.3, 30.0)
    assert drive.startswith("patch 2 (on section 2) whose authority d_ep is 30 % lower for negative drive, "
                            "switching over about ±30 V")
    bend = describe_damage("d_ep_i", 0, "on_pos", "delta1", -0.35, 0.0)
    assert "patch 1" in bend and "for δ1 > 0" in bend and "debonded" in bend
    assert class_stem("k", 0, "on_neg", "z3") == "Section1StiffnessTipNegative"
    assert class_stem("d_ep_i", 0, "on_pos_soft", "delta1") == "Patch1CouplingBendOpeningPositive"
    assert class_stem("k", 2, "on_neg_grow", "delta3") == "Section3StiffnessGrowingNegative"


#: (dictionary term, its coefficient and shape, the blind class, its values, how close): the logistic edge
#: 1/(1 + e^(−δ/w)) is (1 + tanh(δ/2w))/2, so the soft gate of width 2w is the same switch; the blind polarity
#: switch reads the terminal voltage, the dictionary the drive demanded (the amplifier's lag between them)
CASES = [
    ("k3_neg_grow_delta3", -0.15, 4e-3, "CrackS3GrowingOpening", {"loss_max": 0.15, "delta_sat": 4e-3}, 1e-3),
    ("d_ep1_pos_soft_delta1", -0.35, 4e-5, "Patch1WeakOnStrain", {"w": 0.35, "w_edge": 2e-5}, 1e-3),
    ("d_ep2_neg_soft_va", -0.3, 30.0, "Patch2WeakNegative", {"w": 0.3, "v_w": 30.0}, 0.05),
    ("k1_neg_z3", -0.2, 0.0, "CrackS1TipSwitch", {"loss": 0.2, "z_w": 1e-6}, 0.02),
    # a coupling fading with its own voltage (the fourth blind set's patch 1, 40 % at +250 V and beyond)
    ("d_ep1_pos_grow_vc", -0.4, 250.0, f"{BLIND4}:Patch1FadesWithPositiveVoltage", {"weak_loss": 0.4}, 1e-3),
]


@pytest.mark.slow
@pytest.mark.parametrize("key, coef, shape, blind, values, close", CASES, ids=[c[0] for c in CASES])
def test_the_emitted_file_moves_the_beam_as_the_damage_written_outside(tmp_path, key, coef, shape, blind, values,
                                                                       close):
    from plant import PlantModel
    from workbench.simulation import synth_record, synth_test, truth_model

    scales = SCALES | {"z3": 3e-3, "delta1": 6e-4, "delta3": 3e-3}
    term = next(t for t in build_dictionary(scales) if t.key == key)
    (cname, gname), = parameter_names_for([term])
    fixed = {cname: coef} | ({gname: shape} if gname is not None else {})
    f = tmp_path / "emitted.py"
    f.write_text(emit_effect_source([term], fixed))
    rec = synth_record(synth_test("sweep", duration_s=1.5), truth_model("table2"), noise={"z3": 2e-6}, seed=1)
    emitted = PlantModel("table2", effects=[str(f)])
    written = PlantModel("table2", effects=[blind if ":" in blind else f"{BLIND}:{blind}"])
    pe, pw = emitted.p_nominal.copy(), written.p_nominal.copy()
    for name, value in fixed.items():
        pe[emitted.param_index(name)] = value
    for name, value in values.items():
        pw[written.param_index(name)] = value
    ze = emitted.simulate(rec.input_signals(), t_out=rec.t, params=pe, rtol=1e-9)["z3_meas"][0]
    zw = written.simulate(rec.input_signals(), t_out=rec.t, params=pw, rtol=1e-9)["z3_meas"][0]
    nominal = PlantModel("table2").simulate(rec.input_signals(), t_out=rec.t, rtol=1e-9)["z3_meas"][0]
    moved = float(np.max(np.abs(zw - nominal)))
    assert moved > 1e-6
    assert float(np.max(np.abs(ze - zw))) <= close * moved


def test_a_coupling_fading_with_its_own_voltage_is_a_member_and_said_so():
    # blind set 4's patch 1 losing coupling in proportion to its positive voltage (up to 250 V): on MBIT.b the
    # nearest member was every patch's coupling switched at +150 V (13.4 %, no patch named)
    fams = _families()
    for i in range(3):
        assert {("d_ep_i", i, "on_pos_grow", "vc"), ("d_ep_i", i, "on_neg_grow", "vc")} <= fams
    assert {("d_ep", -1, "on_pos_grow", "vc"), ("d_ep", -1, "on_neg_grow", "vc")} <= fams
    assert ("d_ep", -1, "on_pos_grow", "vc") in _families(driven=False)
    words = describe_damage("d_ep_i", 0, "on_pos_grow", "vc", -0.4, 250.0)
    assert words.startswith("patch 1 (on section 1) whose authority d_ep is 40 % lower once its voltage reaches "
                            "+250 V, in proportion to the voltage from 0 V up to there and not at all for negative")
    every = describe_damage("d_ep", -1, "on_neg_grow", "vc", 0.1, 80.0)
    assert every.startswith("all three patches' authority d_ep is 10 % higher once its voltage reaches −80 V")

