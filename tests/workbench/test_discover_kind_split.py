"""One event, two places, another kind (issue 26, ``workbench/discover/_change_kinds.py``): sections 2 and 3 each
losing 12 % at 7.5 s of a 15 s sweep (blind set 6) were kept as a mass m3 stepping up at 7.48 s (116 σ): a heavier tip
lowers the modes as two softer sections do. The kept step is probed as every other kind in every pair of places at
its instant, the kept step off. Here the probes' construction and the step's rule with the refit faked."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import workbench.discover._change_kinds as ck
from workbench.discover import build_dictionary
from workbench.discover._dictionary_code import dictionary_parameter_names
from workbench.discover._rounds import SearchProgress

SCALES = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 1e-3), ("ddelta", 0.1)) for i in (1, 2, 3)} \
    | {"vc": 50.0, "va": 100.0, "ic": 2e-3, "one": 1.0, "t": 15.0}


@pytest.fixture(scope="module")
def dictionary():
    terms = build_dictionary(SCALES)
    return terms, dictionary_parameter_names(terms)


def _slot(terms, key: str) -> int:
    return next(k for k, t in enumerate(terms) if t.key == key)


def test_every_other_kind_is_probed_in_every_pair_of_places_at_the_kept_instant(dictionary):
    terms, names = dictionary
    kept = _slot(terms, "m3_step_t")
    tries = ck.kind_tries(terms, names, [kept], 7.48)
    pairs = {(terms[a].key, terms[b].key) for (a, b), _ in tries}
    assert ("k2_step_t", "k3_step_t") in pairs and ("k1_step_t", "k2_step_t") in pairs
    assert ("c1_step_t", "c3_step_t") in pairs and ("d_ep1_step_t", "d_ep2_step_t") in pairs
    assert ("m1_step_t", "m2_step_t") in pairs and not any("m3" in a or "m3" in b for a, b in pairs)
    for (a, b), setting in tries:
        assert setting[names[kept][0]] == 0.0  # the kept step off
        assert setting[str(names[a][1])] == setting[str(names[b][1])] == 7.48  # both at its instant
        ca, cb = setting[names[a][0]], setting[names[b][0]]
        assert cb > -0.9 and cb / ca in (0.5, 1.0, 2.0)
        if terms[a].param == "k":
            assert ca < 0.0  # a stiffness is lost
        if terms[a].param == "c":
            assert ca > 0.0  # damping is gained
    k23 = [s for (a, b), s in tries if (terms[a].key, terms[b].key) == ("k2_step_t", "k3_step_t")]
    assert {round(s[names[_slot(terms, "k2_step_t")][0]], 3) for s in k23} == {-0.05, -0.1, -0.2, -0.3}


def _progress(terms, names, kept: int, held: float) -> SearchProgress:
    values = {n: 0.0 for pair in names for n in pair if n} | {names[kept][0]: 0.13, str(names[kept][1]): 7.48}
    state = SimpleNamespace(values=values, kept=[kept])
    return SearchProgress(state=state, current_held=held, current_train=held, twins={kept: ["x"]}, stderr={},
                           outcome=None, rounds=[], n_sims=0, timings={"refit_s": 0.0})


@pytest.mark.parametrize(("refit_held", "replaced"), [(1.2, True), (110.0, False)])
def test_the_best_pair_replaces_the_kept_step_only_when_it_removes_the_share(monkeypatch, dictionary, refit_held,
                                                                             replaced):
    terms, names = dictionary
    kept = _slot(terms, "m3_step_t")
    setup = SimpleNamespace(terms=terms, names=names, targets=[object()], models=[object()], n_held=1875,
                            scales={"t": 15.0})
    progress = _progress(terms, names, kept, 116.2)
    k2, k3 = _slot(terms, "k2_step_t"), _slot(terms, "k3_step_t")

    def scores(targets, models, values, settings, threads):  # the k2 + k3 pair at −10 % each scores best, at 7.5 s
        g = str(names[k3][1])
        return [1.0 + abs(s[g] - 7.5) if s.get(names[k2][0]) == -0.1 and s.get(names[k3][0]) == -0.1 else 50.0
                for s in settings]

    out = SimpleNamespace(ok=True, held_rms_sigma=refit_held, train_rms_sigma=refit_held, estimates=[],
                          values={names[k2][0]: -0.12, names[k3][0]: -0.12})
    monkeypatch.setattr(ck, "whole_scores", scores)
    monkeypatch.setattr(ck, "Objective", lambda *a, **kw: SimpleNamespace(n_sims=5))
    monkeypatch.setattr(ck, "refine", lambda obj, start, nfev: out)
    ck.kind_split_change(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12), 0.25)
    assert (progress.state.kept == [k2, k3]) is replaced
    assert progress.rounds[-1]["kind_split"]["as"] == ["k2_step_t", "k3_step_t"]
    if replaced:
        assert progress.state.values[names[kept][0]] == 0.0 and progress.state.values[names[k3][0]] == -0.12
        assert kept not in progress.twins and progress.current_held == 1.2
        assert progress.state.values[str(names[k2][1])] == pytest.approx(7.5)  # the common onset scanned to 7.5 s
    else:
        assert progress.state.kept == [kept] and progress.current_held == 116.2


def test_no_kind_split_near_the_noise_or_for_a_term_not_a_step(monkeypatch, dictionary):
    terms, names = dictionary
    monkeypatch.setattr(ck, "whole_scores", lambda *a: pytest.fail("probed"))
    settings = SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12)
    setup = SimpleNamespace(terms=terms, names=names, targets=[], models=[], n_held=1875, scales={"t": 15.0})
    ck.kind_split_change(setup, _progress(terms, names, _slot(terms, "m3_step_t"), 2.5), settings, 0.25)
    ck.kind_split_change(setup, _progress(terms, names, _slot(terms, "k3_pos_delta3"), 50.0), settings, 0.25)
