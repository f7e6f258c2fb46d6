"""Every file ``shm discover --emit`` writes loads (issue 26 point 4): the writer's names are unique for any set of
dictionary terms, a switched-off term still gives valid ranges, and an emitted file simulates what the dictionary
term simulates."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

from plant import resolve_effect
from workbench.discover._dictionary import Term
from workbench.discover._effect_writer import emit_effect_source, parameter_names_for


def _load(tmp_path: Path, src: str, stem: str = "emitted"):
    f = tmp_path / f"{stem}.py"
    f.write_text(src)
    return resolve_effect(str(f))


def test_two_terms_of_one_key_emit_a_file_that_loads(tmp_path):
    # MBIT.a: discover kept a stop below the tip twice (two thresholds of one form): the file repeated
    # c_m3_neg_z3 and `shm fit --add` refused it ("parameter 'c_m3_neg_z3' declared twice")
    terms = [Term("force_mass", 2, "z3", "neg", 1e-3), Term("force_mass", 2, "z3", "neg", 2.5e-3)]
    names = parameter_names_for(terms)
    assert len({n for pair in names for n in pair}) == 4
    values = {names[0][0]: -5.0, names[0][1]: 1e-3, names[1][0]: -12.0, names[1][1]: 2.5e-3}
    cls = _load(tmp_path, emit_effect_source(terms, values))
    assert cls.__name__ == "DiscoveredMass3ContactBelowPlus"
    got = {p.name: p for p in cls.parameters}
    assert cls.guess() == values and set(got) == set(values)


@pytest.mark.parametrize("coef", [0.0, -0.0])
def test_a_switched_off_term_emits_a_file_that_loads(tmp_path, coef):
    term = Term("force_section", 1, "delta2", "clip", 2e-5)
    cname, gname = parameter_names_for([term])[0]
    cls = _load(tmp_path, emit_effect_source([term], {cname: coef, gname: 2e-5}))
    rng = cls.fit_range(cname)
    assert rng.lower < 0.0 < rng.upper


# ---------------------------------------------------------------------------------------------------------------
# the whole dictionary: every term's file loads; drawn terms simulate what the dictionary simulates and refit


@pytest.fixture(scope="module")
def short_sweep(tmp_path_factory):
    """A 1.5 s sweep on the nominal model, its targets, signal scales and the dictionary's terms (with the time
    gates: the same structure as any driven record's, so the compiled dictionary kernel is shared)."""
    from board_config import load_parameter_set
    from workbench.discover import build_dictionary, signal_scales
    from workbench.fit import model_factory, prepare_targets
    from workbench.records import write_record
    from workbench.simulation import synth_record, synth_test, truth_model

    spec = synth_test("sweep", duration_s=1.5)
    rec = synth_record(spec, truth_model("table2"), noise={"z3": 2e-6}, seed=3)
    path = tmp_path_factory.mktemp("emitted") / "nominal.csv"
    write_record(rec, path)
    base = load_parameter_set("table2")
    targets = prepare_targets([rec], model_factory(base, []), holdout="blocks", n_blocks=4, max_rate_Hz=250.0)
    scales, sig = signal_scales(targets)
    return {"spec": spec, "record": rec, "path": path, "base": base, "targets": targets, "scales": scales,
            "sig": sig, "terms": build_dictionary(scales)}


def _switches(term: Term) -> list[float]:
    """Switching points off zero for a sign gate (half its refit range either side; six digits, as emitted)."""
    if term.form not in ("on_pos", "on_neg") or term.shape_range is None:
        return []
    return [float(f"{0.5 * x:.6g}") for x in term.shape_range]


def _widths(term: Term, scales) -> list[float]:
    """Widths to draw for a term whose width the dictionary fits: 0 (its sharp default) or a wide one — a step's edge
    over a tenth of the record, a ramp settling over a third of it, a switch over a fifth of its signal's scale."""
    if term.form == "on_step":
        return [0.0, 0.1 * scales["t"]]
    if term.form == "on_ramp":
        return [0.0, 0.3 * scales["t"]]
    if term.form in ("on_pos", "on_neg") and scales.get(term.signal, 0.0) > 0.0:
        return [0.0, 0.2 * scales[term.signal]]
    return [0.0]


def _family(term: Term) -> tuple[str, str, str]:
    return term.placement, term.form, term.param or term.signal


def test_the_dictionary_spans_the_damage_family(short_sweep):
    """Every core parameter's contribution meets a time step and ramp; a section's stiffness and damping the sign of
    its deflection and of its rate, and a gap; the patch parameters the drive's and the charge's sign; one patch's
    own coupling both signs and time (issue 26 point 3)."""
    fams = {(t.param, t.form, t.signal) for t in short_sweep["terms"] if t.placement == "damage"}
    for param in ("k", "c", "m", "d_ep", "alpha_h", "beta_h", "R_ep", "C_ep"):
        assert {(param, "on_step", "one"), (param, "on_ramp", "one")} <= fams, param
    for i in (1, 2, 3):
        signs = ("on_pos", "on_neg", "on_pos_soft", "on_neg_soft")  # each on δ_i and δ̇_i, hard and smooth edge
        growing = ("on_pos_grow", "on_neg_grow", "on_pos_grow2", "on_neg_grow2")  # the share with the opening (²)
        assert {(p, g, f"{s}{i}") for p in ("k", "c") for g in signs for s in ("delta", "ddelta")} \
            | {(p, g, f"delta{i}") for p in ("k", "c") for g in (*growing, "on_gap")} <= fams
    for param in ("d_ep", "alpha_h", "beta_h", "R_ep", "C_ep"):
        assert {(param, "on_neg", "va"), (param, "on_pos", "vc")} <= fams
    for i in range(3):  # one patch's own coupling, by the drive's and its own charge's sign (a single weak patch)
        # and by the sense of its charging current, sharp and smooth (a coupling lost while it charges)
        charging = {("d_ep_i", g, "ic") for g in ("on_pos", "on_neg", "on_pos_soft", "on_neg_soft", "on_pos_sat",
                                                  "on_neg_sat")}
        fading = {("d_ep_i", g, "vc") for g in ("on_pos_grow", "on_neg_grow", "on_pos_sat", "on_neg_sat", "on_gap",
                                                "on_excess")}
        assert {("d_ep_i", g, s) for g in ("on_pos", "on_neg") for s in ("va", "vc")} | charging | fading | {
            ("d_ep_i", "on_step", "one"), ("d_ep_i", "on_ramp", "one")} <= {
            (t.param, t.form, t.signal) for t in short_sweep["terms"] if t.placement == "damage" and t.index == i}
    steps = sorted(t.shape for t in short_sweep["terms"] if t.key == "k2_step_t")
    ranges = [t.shape_range for t in short_sweep["terms"] if t.key == "k2_step_t"]
    assert len(steps) >= 3 and min(r[0] for r in ranges) == 0.0  # onsets and their refit ranges span the record
    assert max(r[1] for r in ranges) == pytest.approx(short_sweep["scales"]["t"])


def test_every_term_of_the_dictionary_emits_a_file_that_loads(short_sweep, tmp_path):
    """Each term alone, at a negative, a positive and a zero coefficient (a sign gate also switching off zero, on
    either side), and all of them in one file."""
    terms = short_sweep["terms"]
    for k, term in enumerate(terms):
        (cname, gname), = parameter_names_for([term])
        for coef, shape in [(c, term.shape) for c in (-0.3, 2.0, 0.0)] + [(-0.3, g) for g in _switches(term)]:
            values = {cname: coef} | ({gname: shape} if gname else {})
            cls = _load(tmp_path, emit_effect_source([term], values), f"t{k}_{int(coef * 10) + 5}")
            assert cls.guess()[cname] == coef and cls.fit_range(cname).lower < cls.fit_range(cname).upper
            if gname:
                assert cls.fit_range(gname).lower <= shape <= cls.fit_range(gname).upper
    names = parameter_names_for(terms)
    values = {c: 0.1 for c, _ in names} | {g: t.shape for t, (_, g) in zip(terms, names) if g}
    cls = _load(tmp_path, emit_effect_source(terms, values), "all_terms")
    assert len(cls.parameters) == len(values)


def _coefficient(term: Term, short_sweep) -> float:
    """A coefficient that moves the tip by about 1 % of its motion (5x the sensitivity step)."""
    from workbench.discover._dictionary_effect import reference_magnitudes, term_scale

    ref = reference_magnitudes(short_sweep["targets"][0].model, short_sweep["scales"])
    return 5.0 * ref[term.placement] / max(term_scale(term, short_sweep["sig"], short_sweep["targets"]), 1e-300)


def _emitted_simulates_like_the_dictionary(short_sweep, tmp_path, chosen, coefs, shapes):
    """The emitted file of ``chosen`` (at ``coefs``, ``shapes`` and each term's width) against the compiled
    dictionary, each term alone: both move the tip alike where both runs integrate. Returns the file, its values and
    which terms' runs integrated."""
    import numpy as np

    from plant import PlantModel
    from workbench.discover import dictionary_parameter_names, dictionary_source, generated_effect
    from workbench.discover._dictionary_code import dictionary_width_names

    terms = short_sweep["terms"]
    names = parameter_names_for(chosen)
    values = {c: v for (c, _), v in zip(names, coefs)} | {g: s for s, (_, g) in zip(shapes, names) if g}
    stem = "emitted_" + "_".join(t.key for t in chosen)
    f = tmp_path / f"{stem[:80]}.py"
    f.write_text(emit_effect_source(chosen, values, effect_name="drawn"))
    # each term alone: the emitted file against the compiled dictionary (the kernel shm discover uses)
    tg = short_sweep["targets"][0]
    base = short_sweep["base"]
    emitted = PlantModel(base, effects=[str(f)])
    dictionary = PlantModel(base, effects=[generated_effect(dictionary_source(terms), "dictionary_driven")])
    dnames = dictionary_parameter_names(terms)
    dwidths = dictionary_width_names(terms)
    pe = np.tile(emitted.p_nominal, (len(chosen), 1))
    pd = np.tile(dictionary.p_nominal, (len(chosen), 1))
    for k, (term, (cname, _), coef) in enumerate(zip(chosen, names, coefs)):
        pe[k, emitted.param_index(cname)] = coef
        for n, other in zip(dnames, terms):
            if n[1] is not None:
                pd[k, dictionary.param_index(n[1])] = other.shape
        a, g = dnames[terms.index(replace(term, width=0.0))]
        pd[k, dictionary.param_index(a)] = coef
        if g is not None:  # the drawn shape (a switching point off zero) in both
            pd[k, dictionary.param_index(g)] = shapes[k]
        h = dwidths.get(terms.index(replace(term, width=0.0)))
        if h is not None and term.width > 0.0:  # the drawn width: a parameter of the dictionary, a literal emitted
            pd[k, dictionary.param_index(h)] = term.width
    # tight tolerance: the two models carry different states (the dictionary's delay lines), so at the default
    # tolerance their steps differ (a current term: 5e-7 m apart at rtol default, 1e-9 m at 1e-9)
    re = emitted.simulate(tg.inputs, t_out=tg.t, params=pe, rtol=1e-9)
    rd = dictionary.simulate(tg.inputs, t_out=tg.t, params=pd, rtol=1e-9)
    ze, zd = re["z3_meas"], rd["z3_meas"]
    nominal = PlantModel(base).simulate(tg.inputs, t_out=tg.t, rtol=1e-9)["z3_meas"][0]
    # a drawn sign can make a term an energy source (viscous force along the root's velocity) whose run diverges or
    # exhausts the steps of a 1e-9 tolerance: such a term is compared where both runs integrate, not here
    ran = (re.status == 0) & (rd.status == 0)
    for k, term in enumerate(chosen):
        if not ran[k]:
            continue
        moved = float(np.max(np.abs(zd[k] - nominal)))
        assert moved > 1e-7, term.key  # the term acts
        # 1e-3 of what the term does, or 10 nm (1/200 of the records' 2 um noise): two different state vectors at
        # rtol 1e-9 drift apart by a few nm on a term that barely acts (beta_h ramp: 3e-9 m of 4e-7 m)
        assert float(np.max(np.abs(ze[k] - zd[k]))) <= max(1e-3 * moved, 1e-8), term.key
    return f, values, ran


@pytest.mark.slow
@settings(max_examples=2, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture],
          phases=(Phase.explicit, Phase.reuse, Phase.generate))  # no shrinking: every example compiles a file
@given(data=st.data())
def test_drawn_terms_emit_files_that_simulate_like_the_dictionary_and_refit(short_sweep, tmp_path, data):
    """Three terms drawn from three families of the whole dictionary (placement × form × gate): the emitted file
    simulates what the compiled dictionary simulates with the same coefficient (each term alone), and in a fresh
    process `shm fit --add FILE` loads it and refits it on a record it generated to the noise floor."""
    import json
    import subprocess
    import sys

    from workbench.records import write_record
    from workbench.simulation import synth_record, truth_model

    terms = short_sweep["terms"]
    families = sorted({_family(t) for t in terms})
    drawn = data.draw(st.lists(st.sampled_from(families), min_size=3, max_size=3, unique=True), label="families")
    chosen = [data.draw(st.sampled_from([t for t in terms if _family(t) == f]), label=str(f)) for f in drawn]
    coefs = [_coefficient(t, short_sweep) * data.draw(st.sampled_from([-1.0, 1.0]), label="sign") for t in chosen]
    shapes = [data.draw(st.sampled_from([t.shape, *_switches(t)]), label="shape") for t in chosen]
    # a fitted width (a step's edge, a ramp's settling time, a switch's edge) or the sharp default
    chosen = [replace(t, width=data.draw(st.sampled_from(_widths(t, short_sweep["scales"])), label="width"))
              for t in chosen]
    f, values, ran = _emitted_simulates_like_the_dictionary(short_sweep, tmp_path, chosen, coefs, shapes)
    assume(bool(ran.any()))
    # a record the emitted effect generates, refitted in a fresh process from its discovered values
    rec = synth_record(short_sweep["spec"], truth_model("table2", [str(f)], values), noise={"z3": 2e-6}, seed=5)
    rec_path = tmp_path / "drawn.csv"
    write_record(rec, rec_path)
    run = subprocess.run([sys.executable, "-m", "shm_cli.main", "fit", str(rec_path), "--params", "table2",
                          "--add", str(f), "--save", str(tmp_path / "refit.toml"), "--force",  # examples share tmp_path
                          "--out", str(tmp_path / "fit"),
                          "--max-nfev", "6", "--json"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout)
    assert out["held_rms_sigma"]["after"] <= 1.5, out["held_rms_sigma"]


def test_terms_with_fitted_widths_emit_files_that_simulate_like_the_dictionary(short_sweep, tmp_path):
    """A step with a wide edge (an S-curve), a ramp that settles and a switch off zero with a wide edge: the width is
    a parameter of the dictionary and a literal of the emitted file, and both move the tip alike."""
    terms, scales = short_sweep["terms"], short_sweep["scales"]
    step = next(t for t in terms if t.key == "k2_step_t")
    ramp = next(t for t in terms if t.key == "k1_ramp_t")
    switch = next(t for t in terms if t.key == "d_ep_neg_va")
    chosen = [replace(step, width=0.1 * scales["t"]), replace(ramp, width=0.3 * scales["t"]),
              replace(switch, width=0.2 * scales["va"])]
    coefs = [_coefficient(t, short_sweep) for t in chosen]
    shapes = [step.shape, ramp.shape, 0.3 * scales["va"]]
    _, _, ran = _emitted_simulates_like_the_dictionary(short_sweep, tmp_path, chosen, coefs, shapes)
    assert ran.all()
