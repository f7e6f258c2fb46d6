"""Sign gates of shm discover's damage family switch at a fitted point G, not only at 0 (issue 26 point 3): a
section's stiffness gated by its own deflection is a bilinear spring — the lost force c·k·(δ − G)⁺, continuous at
G — and every other sign gate a step at G (a patch weak below +60 V of drive). Screened at G = 0 (today's terms,
unchanged), refitted within ± SWITCH_RANGE of the signal's scale, said in words when G is away from 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.discover import build_dictionary, dictionary_source
from workbench.discover._dictionary import Term, form_values
from workbench.discover._effect_writer import describe_term, emit_effect_source, formula, parameter_names_for
from workbench.discover._gate_words import describe_damage
from workbench.discover._gates import SWITCH_RANGE, gate_code, gate_values
from workbench.discover._search import free_for

SCALES = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 6e-4), ("ddelta", 0.1))
          for i in (1, 2, 3)} | {"vc": 50.0, "va": 100.0, "t": 6.0}

#: a bilinear section 2 written outside the dictionary (a hard switch): beyond δ2 > d_sw its spring loses a share
BILINEAR_TRUTH = '''
from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_S, P_K, X_DELTA


class BilinearSection2(PhysicalEffect):
    name = "truth_bilinear_s2"
    parameters = (Parameter("loss", "1", 0.0, 0.0, 0.9, "share of k2 lost beyond d_sw"),
                  Parameter("d_sw", "m", 0.0, -1.0, 1.0, "deflection where section 2 switches"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA + 1] - p[po + 1]
        if d > 0.0:
            bus[B_S + 1] += p[po] * p[P_K + 1] * d
'''


def test_the_hinge_is_the_lost_force_beyond_the_switching_point_and_today_s_gate_at_zero():
    d = np.linspace(-1e-3, 1e-3, 401)
    t = np.zeros_like(d)
    for g in (0.0, 3e-4, -2e-4):
        far = np.abs(d - g) > 1e-6  # beyond the smoothing width (1e-7 m)
        pos = gate_values("on_pos", d, g, t, "m", hinge=True)
        neg = gate_values("on_neg", d, g, t, "m", hinge=True)
        # less its value at rest: no force at δ = 0, a corner on the far side of rest included (blind set 4's crack
        # propped open at rest)
        assert np.allclose(pos[far], (np.maximum(d - g, 0.0) - max(-g, 0.0))[far], rtol=0, atol=1e-12)
        assert np.allclose(neg[far], (np.minimum(d - g, 0.0) - min(-g, 0.0))[far], rtol=0, atol=1e-12)
        assert abs(gate_values("on_pos", np.zeros(1), g, np.zeros(1), "m", hinge=True)[0]) < 1e-12
        assert np.all(np.isfinite(pos)) and np.all(np.abs(np.diff(pos)) <= np.diff(d) + 1e-15)  # continuous at G
    # at G = 0 the hinge is exactly the step gate times δ: the screened terms are today's
    assert np.array_equal(gate_values("on_pos", d, 0.0, t, "m", hinge=True), d * gate_values("on_pos", d, 0.0, t, "m"))
    code = gate_code("on_pos", "k", "delta2").replace("math.tanh", "np.tanh")
    assert np.allclose(eval(code, {"np": np, "S": d, "G": 3e-4, "H": 1e-7}),
                       gate_values("on_pos", d, 3e-4, t, "m", hinge=True))
    assert gate_code("on_pos", "c", "delta2") != code  # damping gated by δ: a step of c·δ̇ at G, not a hinge


def test_the_step_gates_switch_at_their_point():
    va = np.linspace(-100.0, 100.0, 201)
    t = np.zeros_like(va)
    below = gate_values("on_neg", va, 60.0, t, "V")
    assert np.all(below[va < 59.9] > 1 - 1e-9) and np.all(below[va > 60.1] < 1e-9)
    assert np.array_equal(form_values("on_neg", va, 60.0, t, 1.0) > 0.5, va < 60.0)


def test_sign_gates_are_screened_at_zero_and_refitted_on_either_side():
    terms = build_dictionary(SCALES)
    gated = [t for t in terms if t.form in ("on_pos", "on_neg")]
    assert gated and all(t.shape == 0.0 for t in gated)
    for t in gated:
        scale = SCALES[t.signal]
        assert t.shape_range == pytest.approx((-SWITCH_RANGE * scale, SWITCH_RANGE * scale))
    k = next(i for i, t in enumerate(terms) if t.key == "k2_pos_delta2")
    names = parameter_names_for(terms)
    cname, gname = names[k]
    assert gname is not None
    start = {cname: -0.1, gname: 0.0}
    g = next(p for p in free_for(terms, names, [k], start, k) if p.name == gname)
    assert (g.lower, g.upper) == pytest.approx((-SWITCH_RANGE * 6e-4, SWITCH_RANGE * 6e-4))
    # the whole dictionary still compiles with the switching points as parameters, unbounded below
    src = dictionary_source(terms)
    compile(src, "<dictionary>", "exec")
    assert "(x[X_DELTA + 1]) - p[po + " in src


def test_words_name_the_switching_point_when_it_is_away_from_zero():
    crack = describe_damage("k", 1, "on_pos", "delta2", -0.3, 3e-4, 2e-5)
    assert "opens for δ2 > 0.3 mm" in crack and "k2 lower by 30 %" in crack and "switching at 0.3 mm" in crack
    # within two standard errors of 0: the sign, as before
    assert describe_damage("k", 1, "on_pos", "delta2", -0.3, 3e-5, 2e-5).startswith(
        "a breathing crack in section 2 that opens for δ2 > 0: stiffness k2 lower by 30 % on that side (")
    patch = describe_damage("d_ep", -1, "on_neg", "va", -0.25, 60.0, 1.5)
    assert "d_ep is 25 % lower while the drive is below +60 V" in patch
    assert "δ1 < −0.2 mm" in describe_damage("k", 0, "on_neg", "delta1", 0.2, -2e-4, 1e-5)
    # the corner on the far side of rest: a crack open at rest, said so (blind set 4, root crack propped open)
    propped = describe_damage("k", 0, "on_pos", "delta1", -0.3, -2.5e-4, 1e-5)
    assert propped.startswith("a crack in section 1 open at rest that closes for δ1 < −0.25 mm: stiffness k1 lower "
                              "by 30 % for δ1 > −0.25 mm")
    term = Term("damage", 1, "delta2", "on_pos", 0.0, "k", (-4.8e-4, 4.8e-4))
    assert describe_term(term, -0.3, 3e-4, 6e-4, 2e-5) == crack
    assert formula(term, "c", "g") == "S_2 += −c · k2 · ((δ2 − g)⁺ − (−g)⁺)   (no force at rest)"


@pytest.mark.parametrize("g", [3e-4, -3e-4, 0.0])
def test_an_emitted_switching_point_loads_with_a_range_around_it(tmp_path, g):
    from plant import resolve_effect

    terms = [Term("damage", 1, "delta2", "on_pos", 0.0, "k", (-4.8e-4, 4.8e-4)),
             Term("damage", -1, "va", "on_neg", 0.0, "d_ep", (-80.0, 80.0)),
             Term("damage", 2, "ddelta3", "on_neg", 0.0, "c")]  # no refit range: one from the gate's width
    names = parameter_names_for(terms)
    shapes = (g, float(f"{2e5 * g:.6g}"), float(f"{10 * g:.6g}"))
    values = {c: -0.2 for c, _ in names} | {gn: s for (_, gn), s in zip(names, shapes) if gn}
    f = tmp_path / "switch.py"
    f.write_text(emit_effect_source(terms, values))
    cls = resolve_effect(str(f))
    assert cls.guess() == values
    for (_, gname), s in zip(names, shapes):
        assert gname is not None
        rng = cls.fit_range(gname)
        assert rng.lower < s < rng.upper and not rng.log


@pytest.mark.slow
def test_the_compiled_hinge_is_a_bilinear_spring_switching_at_g(tmp_path):
    """The emitted file of the hinge (its compiled kernel) against a bilinear spring written outside: one motion."""
    from plant import PlantModel
    from workbench.simulation import synth_record, synth_test, truth_model

    truth = tmp_path / "truth.py"
    truth.write_text(BILINEAR_TRUTH)
    term = Term("damage", 1, "delta2", "on_pos", 0.0, "k", (-4.8e-4, 4.8e-4))
    (cname, gname), = parameter_names_for([term])
    assert gname is not None
    f = tmp_path / "hinge.py"
    f.write_text(emit_effect_source([term], {cname: -0.3, gname: 1e-4}))
    rec = synth_record(synth_test("sweep", duration_s=1.5), truth_model("table2"), noise={"z3": 2e-6}, seed=1)
    inputs, t = rec.input_signals(), rec.t
    emitted = PlantModel("table2", effects=[str(f)])
    written = PlantModel("table2", effects=[f"{truth}:BilinearSection2"])
    pe, pw = emitted.p_nominal.copy(), written.p_nominal.copy()
    pe[emitted.param_index(cname)] = -0.3
    pe[emitted.param_index(gname)] = 1e-4
    pw[written.param_index("loss")] = 0.3
    pw[written.param_index("d_sw")] = 1e-4
    ze = emitted.simulate(inputs, t_out=t, params=pe, rtol=1e-9)["z3_meas"][0]
    zw = written.simulate(inputs, t_out=t, params=pw, rtol=1e-9)["z3_meas"][0]
    nominal = PlantModel("table2").simulate(inputs, t_out=t, rtol=1e-9)["z3_meas"][0]
    assert np.all(np.isfinite(ze))
    moved = float(np.max(np.abs(zw - nominal)))
    assert moved > 1e-6  # the spring switches within the motion
    assert float(np.max(np.abs(ze - zw))) <= 1e-3 * moved


@pytest.mark.slow
def test_discover_finds_a_bilinear_spring_switching_off_zero(tmp_path):
    """A 6 s sweep whose section 2 loses 30 % of k2 beyond δ2 > 0.2 mm: discover's one term is section 2's hinge,
    the switching point within two standard errors of the truth and said in words."""
    from workbench.discover import discover
    from workbench.simulation import synth_record, synth_test, truth_model

    truth = tmp_path / "truth.py"
    truth.write_text(BILINEAR_TRUTH)
    rec = synth_record(synth_test("sweep", duration_s=6.0),
                       truth_model("table2", [f"{truth}:BilinearSection2"], {"loss": 0.3, "d_sw": 2e-4}),
                       noise={"z3": 2e-6}, seed=11)
    d = discover([rec], "table2", max_terms=1)
    assert d.verdict == "found", d.message
    found = d.terms[0]
    assert found.term.key == "k2_pos_delta2", d.message
    assert found.coef == pytest.approx(-0.3, abs=0.03)
    assert d.outcome is not None
    se = next(e.stderr for e in d.outcome.estimates if e.name.startswith("g_"))  # the one shape refitted
    assert abs(found.shape - 2e-4) <= max(2 * se, 1e-6), (found.shape, se)
    assert "opens for δ2 > 0.2" in found.words and "mm" in found.words, found.words


@pytest.mark.slow
def test_the_dictionary_kernel_and_the_emitted_file_switch_at_the_same_point(tmp_path):
    """Switching points off zero (a hinge at +0.4 of δ2's scale, a drive step at −0.3 of the drive's): the compiled
    dictionary shm discover searches with and the emitted file simulate the same motion."""
    from board_config import load_parameter_set
    from plant import PlantModel
    from workbench.discover import dictionary_parameter_names, generated_effect, signal_scales
    from workbench.fit import model_factory, prepare_targets
    from workbench.simulation import synth_record, synth_test, truth_model

    rec = synth_record(synth_test("sweep", duration_s=1.5), truth_model("table2"), noise={"z3": 2e-6}, seed=3)
    base = load_parameter_set("table2")
    targets = prepare_targets([rec], model_factory(base, []), holdout="blocks", n_blocks=4, max_rate_Hz=250.0)
    scales, _ = signal_scales(targets)
    terms = build_dictionary(scales)
    chosen = [next(t for t in terms if t.key == key) for key in ("k2_pos_delta2", "d_ep_neg_va")]
    shapes = [float(f"{0.4 * scales['delta2']:.6g}"), float(f"{-0.3 * scales['va']:.6g}")]
    names = parameter_names_for(chosen)
    values = {c: -0.3 for c, _ in names} | {g: s for (_, g), s in zip(names, shapes) if g}
    f = tmp_path / "switches.py"
    f.write_text(emit_effect_source(chosen, values))
    emitted = PlantModel(base, effects=[str(f)])
    dictionary = PlantModel(base, effects=[generated_effect(dictionary_source(terms), "dictionary_driven")])
    dnames = dictionary_parameter_names(terms)
    pe = np.tile(emitted.p_nominal, (2, 1))
    pd = np.tile(dictionary.p_nominal, (2, 1))
    for k, term in enumerate(chosen):
        for other_names, other in zip(dnames, terms):
            if other_names[1] is not None:
                pd[k, dictionary.param_index(other_names[1])] = other.shape
        for j, (c, _) in enumerate(names):  # each term alone in the emitted file
            pe[k, emitted.param_index(c)] = -0.3 if j == k else 0.0
        a, g = dnames[terms.index(term)]
        assert g is not None
        pd[k, dictionary.param_index(a)] = -0.3
        pd[k, dictionary.param_index(g)] = shapes[k]
    tg = targets[0]
    ze = emitted.simulate(tg.inputs, t_out=tg.t, params=pe, rtol=1e-9)["z3_meas"]
    zd = dictionary.simulate(tg.inputs, t_out=tg.t, params=pd, rtol=1e-9)["z3_meas"]
    nominal = PlantModel(base).simulate(tg.inputs, t_out=tg.t, rtol=1e-9)["z3_meas"][0]
    for k, term in enumerate(chosen):
        moved = float(np.max(np.abs(zd[k] - nominal)))
        assert moved > 1e-7, term.key
        assert float(np.max(np.abs(ze[k] - zd[k]))) <= max(1e-3 * moved, 1e-8), term.key


# ---------------------------------------------------------------------------------------------------------------
# a smooth edge: the sign gate of a section's own deflection with a fitted width (a crack that opens gradually)

#: a smooth root crack written outside the dictionary (the unseen-damage cases' own: share a_sm1, width w_sm1)
UNSEEN = Path(__file__).parents[1] / "workbench_unseen_damage.py"


def test_soft_gates_open_over_their_edge_width_and_are_members_for_the_sections():
    d = np.linspace(-1e-3, 1e-3, 201)
    t = np.zeros_like(d)
    assert np.allclose(gate_values("on_pos_soft", d, 2e-4, t, "m"), 0.5 * (1 + np.tanh(d / 2e-4)))
    assert np.allclose(gate_values("on_neg_soft", d, 2e-4, t, "m"), 0.5 * (1 - np.tanh(d / 2e-4)))
    terms = build_dictionary(SCALES)
    soft = {(t.param, t.form, t.signal): t for t in terms if t.form in ("on_pos_soft", "on_neg_soft")}
    for param in ("k", "c"):
        for i in (1, 2, 3):
            for form in ("on_pos_soft", "on_neg_soft"):
                term = soft[(param, form, f"delta{i}")]
                assert term.shape == pytest.approx(0.2 * 6e-4) and term.shape_range is None  # refit: ×4 either way
    words = describe_damage("k", 0, "on_pos_soft", "delta1", -0.3, 2e-4)
    assert words.startswith("a breathing crack in section 1 that opens gradually for δ1 > 0")
    assert "±200 µm" in words and "k1 lower by 30 %" in words


@pytest.mark.slow
def test_the_compiled_soft_gate_is_a_crack_that_opens_gradually(tmp_path):
    """The emitted file of k1 × soft gate against a smooth crack written outside: one motion."""
    from plant import PlantModel
    from workbench.simulation import synth_record, synth_test, truth_model

    term = next(t for t in build_dictionary(SCALES) if t.key == "k1_pos_soft_delta1")
    (cname, gname), = parameter_names_for([term])
    assert gname is not None
    f = tmp_path / "soft.py"
    f.write_text(emit_effect_source([term], {cname: -0.3, gname: 2e-4}))
    rec = synth_record(synth_test("sweep", duration_s=1.5), truth_model("table2"), noise={"z3": 2e-6}, seed=1)
    emitted = PlantModel("table2", effects=[str(f)])
    written = PlantModel("table2", effects=[f"{UNSEEN}:SmoothCrackRoot"])
    pe, pw = emitted.p_nominal.copy(), written.p_nominal.copy()
    pe[emitted.param_index(cname)] = -0.3
    pw[written.param_index("a_sm1")] = 0.3
    pw[written.param_index("w_sm1")] = 2e-4
    ze = emitted.simulate(rec.input_signals(), t_out=rec.t, params=pe, rtol=1e-9)["z3_meas"][0]
    zw = written.simulate(rec.input_signals(), t_out=rec.t, params=pw, rtol=1e-9)["z3_meas"][0]
    nominal = PlantModel("table2").simulate(rec.input_signals(), t_out=rec.t, rtol=1e-9)["z3_meas"][0]
    moved = float(np.max(np.abs(zw - nominal)))
    assert moved > 1e-6
    assert float(np.max(np.abs(ze - zw))) <= 1e-3 * moved
