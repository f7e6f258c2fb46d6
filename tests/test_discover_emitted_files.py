"""Every file ``shm discover --emit`` writes loads (issue 26 point 4): the writer's names are unique for any set of
dictionary terms, a switched-off term still gives valid ranges, and an emitted file simulates what the dictionary
term simulates."""

from __future__ import annotations

from pathlib import Path

import pytest

from plant import resolve_effect
from workbench.discovery_dictionary import Term
from workbench.effect_writer import emit_effect_source, parameter_names_for


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
    rng = cls.fit_ranges[cname]
    assert rng.lower < 0.0 < rng.upper
