"""shm diagnose / workbench.diagnose: a hidden library effect is named and explained, a clean record is "nothing
missing", an effect outside the candidates is "not explained" with where it fails, unstable or flat candidates are
rejected, and the CLI writes its report and refuses bad input with clear errors."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from board_config.json_values import to_jsonable
from plant import Parameter, PhysicalEffect
from plant.layout import B_FM, B_ZD, Y_Z3_MEAS
from shm_cli.main import main
from workbench.diagnose import diagnose
from workbench.fit import FitError
from workbench.records import write_record
from workbench.simulation import synth_record, synth_test, truth_model

NOISE = 2e-6


def _record(effects=(), values=None, kind="mbit-b", seed=0, **spec):
    return synth_record(synth_test(kind, **spec), truth_model("table2", list(effects), values or {}),
                        noise={"z3": NOISE}, seed=seed)


@pytest.fixture(scope="module")
def creep_diagnosis():
    rec = _record(["piezo_creep"], {"gamma_creep": 0.03, "tau_creep": 0.4})
    return diagnose([rec], "table2")


def test_hidden_creep_is_named_with_signature_and_estimates(creep_diagnosis):
    d = creep_diagnosis
    assert d.verdict == "missing" and d.winner is not None and d.winner.effect == "piezo_creep"
    assert d.ranked_names[0] == "piezo_creep" and d.found == ("piezo_creep",)
    # every library effect and every parameter candidate is ranked; the most promising of each kind fitted in full
    assert {"geometric_stiffening", "m3", "stiffness", "electrical"} <= set(d.ranked_names)
    fitted = [c for c in d.ranking if c.outcome is not None]
    assert {c.kind for c in fitted} == {"effect", "parameter"} and len(fitted) >= 6
    assert all(c.status == "screened out" for c in d.ranking if c.outcome is None)
    w = d.winner
    assert w.held_rms_sigma < 1.5 < d.baseline_held_rms_sigma
    assert w.held_reduction > 0.9 and w.delta_bic_held > 0
    est = {e.name: e for e in w.outcome.estimates}
    assert est["gamma_creep"].value == pytest.approx(0.03, rel=0.1)
    assert 0 < est["gamma_creep"].stderr < 0.01
    # the verdict explains itself: the effect, the error reduction, the estimates and the signature in words
    for text in ("piezo_creep", "σ", "gamma_creep", "Slow drift", "Residual tests failed by the nominal model",
                 "shm fit '<synth mbit-b>' --params table2 --add piezo_creep"):
        assert text in d.message
    assert d.fit_command.startswith("shm fit") and not d.next_command
    # accepted candidates are ranked by their held-out ΔBIC
    acc = [c for c in d.ranking if c.accepted]
    assert all(a.delta_bic_held >= b.delta_bic_held for a, b in itertools.pairwise(acc))
    json.dumps(to_jsonable(d.to_dict()))  # JSON-able for --json


def test_clean_record_is_nothing_missing():
    d = diagnose([_record(seed=5)], "table2")
    assert d.verdict == "nothing_missing" and d.winner is None
    assert "Nothing missing" in d.message
    assert not any(c.accepted for c in d.ranking)
    assert d.baseline_held_rms_sigma < 1.25


def test_effect_outside_the_candidates_is_not_explained_and_localised():
    rec = _record(["amplifier_current_limit"], {"I_max": 0.02})
    d = diagnose([rec], "table2", ["thermal_drift", "root_compliance"])
    assert d.verdict == "unexplained" and d.winner is None
    assert "Not explained by the library" in d.message and "Where it fails" in d.message
    assert d.next_command.startswith("shm discover") and "--emit my_effect.py" in d.message
    assert d.where_it_fails and "residual RMS" in d.where_it_fails[0]


def test_unstable_and_flat_candidates_are_rejected():
    class NegativeDamping(PhysicalEffect):
        """Pumps energy into the tip: the free run grows without bound."""

        name = "negative_damping"
        description = "negative damping on the tip mass"
        parameters = (Parameter("c_neg", "N*s/m", 2.0, 1.0, 5.0, "negative damping"),)

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            bus[B_FM + 2] += p[po] * bus[B_ZD + 2]

    class DeadSensor(PhysicalEffect):
        """A laser that reads (almost) nothing."""

        name = "dead_sensor"
        description = "laser gain near zero"
        parameters = (Parameter("g_dead", "1", 1e-4, 0.0, 1e-3, "sensor gain"),)

        @staticmethod
        def output(t, x, p, bus, y, so, po, yo):
            y[Y_Z3_MEAS] *= p[po]

    rec = _record(["dielectric_leakage"], {"G_leak": 2e-5}, duration_s=1.5)
    d = diagnose([rec], "table2", [NegativeDamping, DeadSensor, "dielectric_leakage"])
    by = {c.effect: c for c in d.ranking}
    assert d.winner is not None and d.winner.effect == "dielectric_leakage"
    assert not by["negative_damping"].stable and "diverge" in by["negative_damping"].rejection
    assert not by["dead_sensor"].stable and "flat" in by["dead_sensor"].rejection
    assert d.ranked_names[-2:] != ["dielectric_leakage"]  # rejected candidates rank last
    assert not by["negative_damping"].accepted and not by["dead_sensor"].accepted


def test_cli_diagnose_report_and_bad_input(tmp_path, capsys):
    rec = _record(["geometric_stiffening"], {"kappa_nl": 2e4}, duration_s=2.0)
    path = write_record(rec, tmp_path / "stiff.csv")
    out = tmp_path / "diag"
    code = main(["diagnose", "--candidates", "geometric_stiffening,dielectric_leakage", "--candidates",
                 "laser_sensor", str(path), "--params", "table2", "--json", "--out", str(out)])
    assert code == 0
    cap = capsys.readouterr()
    result = json.loads(cap.out)  # --json: stdout is exactly one JSON document; the table goes to stderr
    assert result["verdict"] == "missing" and result["winner"] == "geometric_stiffening"
    assert "Missing effect: geometric_stiffening" in cap.err
    for f in ("diagnosis.json", "diagnosis.html", "ranking.png", "overlay.png"):
        assert (out / f).stat().st_size > 500
    html = (out / "diagnosis.html").read_text()
    assert "data:image/png;base64" in html and "geometric_stiffening" in html
    # bad input: unknown candidate, failing import path, too short to hold out, a frequency-response table
    assert main(["diagnose", str(path), "--candidates", "no_such_effect", "--out", str(out)]) == 2
    assert "unknown effect 'no_such_effect'" in capsys.readouterr().err
    assert main(["diagnose", str(path), "--candidates", "nopkg.nomod:X", "--out", str(out)]) == 2
    assert "cannot import module 'nopkg.nomod'" in capsys.readouterr().err
    short = write_record(_record(duration_s=0.1, t_step_s=0.02), tmp_path / "short.csv")
    assert main(["diagnose", str(short), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "too short to hold out" in err and "short.csv" in err
    with pytest.raises(FitError, match="frequency-response table"):
        from workbench.simulation import synth_frf

        diagnose([synth_frf(synth_test("frf", n_freqs=5), truth_model("table2"))], "table2", ["laser_sensor"])
    assert np.isfinite(result["baseline"]["held_rms_sigma"])
