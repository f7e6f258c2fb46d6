"""Resonance peaks placed between a coarse grid's frequencies (issue 27.8): an FRF table of a plant with k3 −20 %
reads 15.77 Hz measured vs 17.07 Hz model, not "16.5 Hz vs 16.5 Hz" (the 30-point grid's nearest sample)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from workbench.compare import find_peaks
from workbench.compare._frf_peaks import grid_spacing, local_maxima, match_peaks


def _one_mode(f: np.ndarray, fn: float, zeta: float) -> np.ndarray:
    s = 2j * np.pi * f
    wn = 2 * np.pi * fn
    return wn ** 2 / (s ** 2 + 2 * zeta * wn * s + wn ** 2) * (1.0 + 0.05 / (1 + s / (2 * np.pi * 10)))


@pytest.mark.parametrize("fn", [15.77, 16.2, 17.07, 18.1])
def test_a_mode_between_coarse_grid_points_is_placed_within_half_a_percent(fn: float) -> None:
    f = np.geomspace(0.5, 50, 30)  # shm synth's default table: 17 % between neighbours
    rng = np.random.default_rng(3)
    for _ in range(10):
        h = _one_mode(f, fn, 0.05) * (1 + 0.01 * rng.standard_normal(f.size)) * np.exp(
            1j * np.radians(0.5) * rng.standard_normal(f.size))
        (p,) = find_peaks(f, h)
        assert p.frequency_Hz == pytest.approx(fn, rel=5e-3)
        assert p.damping_ratio == pytest.approx(0.05, rel=0.2)
        assert p.grid_Hz in f and p.spacing_Hz == pytest.approx(grid_spacing(f, int(np.flatnonzero(f == p.grid_Hz)[0])))
        assert "rational fit" in p.method


def test_a_peak_without_the_phase_of_a_mode_falls_back_to_a_parabola_and_says_so() -> None:
    f = np.geomspace(1, 100, 30)
    bump = np.exp(-((np.log(f) - np.log(17.3)) ** 2) / 0.05) + 0.01  # zero phase: no resonance
    (p,) = find_peaks(f, bump.astype(complex))
    assert p.method.startswith("parabola") and math.isnan(p.damping_ratio)
    assert p.frequency_Hz == pytest.approx(17.3, rel=0.01) and p.magnitude == pytest.approx(1.01, rel=0.02)


def test_local_maxima_ignore_ripples_and_order_by_height() -> None:
    mag = np.array([1.0, 1.01, 1.0, 5.0, 1.0, 0.5, 2.0, 0.4])
    assert local_maxima(mag) == [3, 6]  # the 1 % ripple at index 1 is no peak


def test_peaks_pair_by_nearest_frequency() -> None:
    f = np.geomspace(1, 100, 400)
    a = find_peaks(f, _one_mode(f, 15.8, 0.05) + 0.3 * _one_mode(f, 34.5, 0.05))
    b = find_peaks(f, _one_mode(f, 17.1, 0.05) + 0.3 * _one_mode(f, 35.6, 0.05))
    pairs = match_peaks(a, b)
    assert [round(p.frequency_Hz, 0) for p, _ in pairs] == [16, 34]
    assert [round(q.frequency_Hz, 0) for _, q in pairs if q is not None] == [17, 36]


def _modes_Hz(k3_factor: float) -> float:
    from board_config import load_parameter_set
    from plant import PlantModel
    from plant.linear import linearise, modal_summary

    base = load_parameter_set("table2")
    m = PlantModel(base.with_values(None, k3=base.values["k3"] * k3_factor), terminal="amplifier")
    return float(modal_summary(linearise(m)).modes[0]["frequency_Hz"])


@pytest.mark.slow
def test_compare_of_the_k3_minus_20_percent_table_finds_both_resonances(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from shm_cli.main import main

    truth, model = _modes_Hz(0.8), _modes_Hz(1.0)  # the linear modes: 15.77 and 17.07 Hz
    assert truth == pytest.approx(15.77, abs=0.01) and model == pytest.approx(17.07, abs=0.01)
    table = tmp_path / "frf_k3.csv"
    assert main(["synth", "--test", "frf", "--deviation", "k3=-0.2", "--out", str(table)]) == 0
    capsys.readouterr()
    assert main(["compare", str(table), "--json", "--out", str(tmp_path / "cmp")]) == 0
    (rec,) = json.loads(capsys.readouterr().out)["records"]
    (pair, *_) = rec["peaks"]["z3"]["pairs"]
    assert pair["measured_Hz"] == pytest.approx(truth, rel=0.01)
    assert pair["model_Hz"] == pytest.approx(model, rel=0.01)
    assert rec["metrics"]["z3"]["peak_measured_Hz"] == pytest.approx(truth, rel=0.01)
    assert rec["metrics"]["z3"]["peak_model_Hz"] == pytest.approx(model, rel=0.01)
    finding = rec["findings"]["z3"][1]
    assert "15.7" in finding and "17.07" in finding and "grid spacing 2.62 Hz" in finding  # the grid's resolution
