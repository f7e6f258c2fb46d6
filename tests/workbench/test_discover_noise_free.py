"""``shm discover`` on a noise-free nominal record (issue 33): "nothing to find", never "found" with more than
100 % of the excess removed; the share of the excess is taken only of a meaningful excess."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from shm_cli.main import main


def test_the_share_of_the_excess_is_at_most_all_of_it_and_needs_an_excess() -> None:
    from workbench.discover._results import excess_share_removed

    assert excess_share_removed(2.0, 0.2, 0.2) == pytest.approx(1.0)  # below the floor removes the whole excess
    assert excess_share_removed(2.0, 1.0, 0.2) == pytest.approx(1.0)
    assert excess_share_removed(2.0, 1.5, 0.2) == pytest.approx((4 - 2.25) / 3)
    assert excess_share_removed(1.0000001, 0.5, 0.2) is None  # no excess over the noise: no percentage at all
    assert excess_share_removed(1.1, 0.5, 0.2) is None


def test_a_noise_free_nominal_record_has_nothing_to_find(tmp_path: Path, capsys) -> None:
    rec = tmp_path / "clean.csv"
    assert main(["synth", "--test", "step", "--duration-s", "1", "--noise", "none", "--out", str(rec)]) == 0
    capsys.readouterr()
    emit = tmp_path / "found.py"
    code = main(["discover", str(rec), "--emit", str(emit), "--out", str(tmp_path / "d"), "--json"])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    summary = json.loads(cap.out)
    assert summary["verdict"] == "not_found", summary["message"]
    assert summary["message"].startswith("Nothing to find"), summary["message"]
    assert not emit.exists()
