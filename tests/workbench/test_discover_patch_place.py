"""Every patch's change in one patch (issue 26, ``_patch_place.py``): blind set 7's patch 2 weak above 150 V of either
polarity (15 s sweep) was kept as "all three patches' authority d_ep is 18.4 % lower above ±170 V", 6.19 σ held out.
Here the step's rule with the probes and refits faked: the counterparts, what moves with the change, and that it
moves only when one patch fits clearly better."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from term_swap_fakes import fake_refits

import workbench.discover._patch_place as pp
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import since_name
from workbench.discover._gates import SINCE_NEVER_S
from workbench.discover._rounds import SearchProgress

TERMS = [Term("damage", -1, "vc", "on_gap", 90.0, "d_ep"),
         *(Term("damage", i, "vc", "on_gap", g, "d_ep_i") for i in range(3) for g in (90.0, 180.0)),
         Term("damage", 1, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0))]  # another form


def test_the_counterparts_are_the_same_change_in_each_patch_once():
    assert pp.one_patch_terms(TERMS, TERMS[0]) == [1, 3, 5]


def test_the_moved_change_keeps_its_shape_and_instant():
    names = [(f"a_{k:02d}", f"g_{k:02d}") for k in range(len(TERMS))]
    values = {"a_00": -0.18, "g_00": 170.0, since_name(0): 4.0, since_name(3): SINCE_NEVER_S}
    assert pp.moved_values(values, names, 0, 3, -0.5) == {"a_00": 0.0, "a_03": -0.5, "g_03": 170.0,
                                                          since_name(3): 4.0}


@pytest.mark.parametrize(("refit_held", "taken"), [(1.3, True), (6.0, False)])
def test_every_patchs_change_moves_to_one_patch_only_when_it_fits_clearly_better(monkeypatch, refit_held, taken):
    names = [(f"a_{k:02d}", f"g_{k:02d}") for k in range(len(TERMS))]
    values = {n: 0.0 for pair in names for n in pair} | {"a_00": -0.184, "g_00": 170.0}
    setup = SimpleNamespace(terms=TERMS, names=names, targets=[], models=[], held_before=65.5, n_held=1875)
    progress = SearchProgress(state=SimpleNamespace(values=values, kept=[0]), current_held=6.19,
                              current_train=6.19, twins={0: ["x"]}, timings={"refit_s": 0.0}, n_sims=0)
    seen: dict = {}

    def whole_scores(targets, models, base, settings, threads):
        seen["probes"] = list(settings)
        return [2.0 if "a_03" in s and abs(s["a_03"] + 0.552) < 1e-9 else 5.0 if "a_05" in s else 9.0
                for s in settings]

    monkeypatch.setattr(pp, "whole_scores", whole_scores)
    fake_refits(monkeypatch, seen, refit_held, {"a_03": -0.6, "g_03": 150.0})
    pp.patch_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert len(seen["probes"]) == 9 and all(p["a_00"] == 0.0 for p in seen["probes"])
    first = seen["start"][0]
    assert first["a_00"] == 0.0 and first["a_03"] == pytest.approx(-0.552) and first["g_03"] == 170.0
    assert len(seen["start"]) == 2 and seen["start"][1]["a_05"] != 0.0  # the two best patches refitted
    assert progress.rounds[-1]["patch_place"]["taken"] is taken
    assert progress.state.kept == ([3] if taken else [0])
