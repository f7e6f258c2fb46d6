"""`shm synth --effect NAME` without a strength (issue 27, point 6).

An effect injected at its neutral values (``geometric_stiffening`` has ``kappa_nl = 0`` by default) leaves the truth
plant the nominal one, so the record equals the nominal record while its header names the effect as the truth.
synth says so on stderr and writes the values it simulated (the neutral ones) and ``truth_neutral_effects`` into the
header; with ``--set`` the effect acts and nothing is said."""

from __future__ import annotations

import numpy as np

from shm_cli.main import main
from workbench.records import load_record

ARGS = ["synth", "--test", "step", "--duration-s", "1", "--rate-hz", "200", "--seed", "4"]


def test_neutral_effect_warns_and_writes_its_values(tmp_path, capsys):
    assert main([*ARGS, "--effect", "geometric_stiffening", "--out", str(tmp_path / "g.csv")]) == 0
    err = capsys.readouterr().err
    assert "warning: --effect geometric_stiffening is at its neutral value (kappa_nl = 0 m^-2)" in err
    assert "--set kappa_nl=VALUE" in err
    prov = load_record(tmp_path / "g.csv").meta["provenance"]
    assert prov["truth_effects"] == ["geometric_stiffening"]
    assert prov["truth_values"] == {"kappa_nl": 0.0}
    assert prov["truth_neutral_effects"] == ["geometric_stiffening"]
    # and it is true: the record is the nominal one
    assert main([*ARGS, "--out", str(tmp_path / "nominal.csv")]) == 0
    a, b = load_record(tmp_path / "g.csv"), load_record(tmp_path / "nominal.csv")
    assert np.array_equal(a["z3"], b["z3"])


def test_an_effect_with_a_strength_is_not_neutral(tmp_path, capsys):
    assert main([*ARGS, "--effect", "geometric_stiffening", "--set", "kappa_nl=2e4", "--json",
                 "--out", str(tmp_path / "s.csv")]) == 0
    assert "neutral" not in capsys.readouterr().err
    prov = load_record(tmp_path / "s.csv").meta["provenance"]
    assert prov["truth_values"] == {"kappa_nl": 2e4} and "truth_neutral_effects" not in prov


def test_the_header_carries_an_effects_default_values(tmp_path, capsys):
    """Values not set on the command line are the simulated defaults: written too, not left out."""
    assert main([*ARGS, "--effect", "dielectric_leakage", "--out", str(tmp_path / "d.csv")]) == 0
    capsys.readouterr()
    prov = load_record(tmp_path / "d.csv").meta["provenance"]
    from plant import resolve_effect

    own = {p.name for p in resolve_effect("dielectric_leakage").own_parameters()}
    assert own and own <= set(prov["truth_values"])
