"""Property-based end-to-end tests of ``shm campaign`` and ``shm campaign-roc`` (issue 15): valid combinations of
MBITs, ranges, run counts, seeds, signs, deviated parameters, noise and batch sizes run in-process; the campaign
must exit 0, write every promised file readable, print one JSON document with --json, and produce its figures with
no numpy/matplotlib warning. ``shm campaign`` works for every n from 1 to 500 (drawn here; exhaustively in
``make fuzz``). Profiles and helpers: ``tests/cli_properties_support.py``."""

from __future__ import annotations

import itertools
import json
import math
import tempfile
from pathlib import Path

import pytest
from cli_properties_support import FUZZ, assert_ok, assert_readable, examples, floats, seeds, shm
from hypothesis import example, given
from hypothesis import strategies as st

#: files `shm campaign` promises (docstring of shm_cli.campaign_cmd)
NUMBERS = ("fig11_table.csv", "fig11_table.md", "paper_comparison.csv", "runs.csv", "traces.npz", "roc.csv",
           "campaign.json", "manifest.json")
FIGURES = ("fig11.png", "fig11.svg", "error_traces.png", "roc.png")


def max_range_pct(params: str, deviated: list[str], sign: str) -> int:
    """The largest deviation (percent, at most 90) that keeps every deviated parameter inside its bounds — the
    documented limit of --ranges (`studies.campaign.spec.check_deviation_bounds`)."""
    from board_config import load_parameter_set
    from studies.campaign.spec import core_bounds

    values, bounds, cap = load_parameter_set(params).values, core_bounds(), 0.90
    for name in deviated:
        nom = values[name]
        lo, hi = bounds.get(name, (-math.inf, math.inf))
        if sign in ("both", "plus") and nom > 0 and math.isfinite(hi):
            cap = min(cap, hi / nom - 1.0)
        if sign in ("both", "minus") and nom > 0 and lo >= 0:
            cap = min(cap, 1.0 - lo / nom - 1e-6)
    return max(1, math.floor(100 * cap - 1e-9))


@st.composite
def range_specs(draw, cap: int = 90) -> str:
    """--ranges in the three documented forms (percent, 0 <= lo < hi <= cap)."""
    steps = [s for s in (5, 10, 15, 20, 25) if s <= cap]
    form = draw(st.sampled_from(["grid", "single", "list"] if steps else ["single", "list"]))
    if form == "grid":
        step = draw(st.sampled_from(steps))
        start = step * draw(st.integers(0, min(3, cap // step - 1)))
        count = draw(st.integers(1, min(4, (cap - start) // step)))
        return f"{start}:{start + count * step}:{step}"
    if form == "single":
        lo = draw(st.integers(0, cap - 1))
        return f"{lo}:{draw(st.integers(lo + 1, cap))}"
    edges = sorted(draw(st.lists(st.integers(0, cap), min_size=2, max_size=5, unique=True)))
    pairs = [f"{a}-{b}" for a, b in itertools.pairwise(edges)]
    return ",".join(draw(st.lists(st.sampled_from(pairs), min_size=1, max_size=len(pairs), unique=True)))


def _check_campaign(out: Path, run, figures: bool) -> dict:
    summary = assert_ok(run, json_out=True)
    assert summary["complete"] is True and summary["integration_failures"] == 0
    for name in NUMBERS + (FIGURES if figures else ()):
        assert_readable(out / name)
    stored = json.loads((out / "campaign.json").read_text())
    assert stored["summary"] == summary["summary"]
    assert stored["figures"] == ("written" if figures else "skipped (--no-figures)")
    for row in summary["summary"]:
        assert 0 <= row["n_detected"] <= row["n_runs"]
        if row["probability"] is not None:
            assert row["ci95_low"] <= row["probability"] <= row["ci95_high"], row
    return summary


@examples(fast=3, fuzz_factor=0.5)
@given(mbit=st.sampled_from(["a", "b", "both"]), n=st.integers(1, 60), seed=seeds,
       sign=st.sampled_from(["both", "minus", "plus"]),
       deviate=st.lists(st.sampled_from(["k3", "alpha_h", "beta_h", "k1", "c3"]), min_size=1, max_size=3,
                        unique=True),
       noise_um=st.one_of(st.just(0.0), floats(0.1, 5.0)), batch=st.integers(1, 40), figures=st.booleans(),
       params=st.sampled_from(["table2", "calibrated"]), data=st.data())
def test_campaign_any_valid_options(mbit, n, seed, sign, deviate, noise_um, batch, figures, params, data):
    ranges = data.draw(range_specs(max_range_pct(params, deviate, sign)), label="ranges")
    with tempfile.TemporaryDirectory(prefix="shm-prop-campaign-") as tmp:
        out = Path(tmp) / "c"
        argv = ["campaign", "--mbit", mbit, "--ranges", ranges, "--n", n, "--seed", seed, "--sign", sign,
                "--deviate", ",".join(deviate), "--noise-um", noise_um, "--batch-size", max(batch, n // 10),
                "--params", params, "--workers", "1", "--no-progress", "--json", "--out", out]
        if not figures:
            argv.append("--no-figures")
        run = shm(*argv)
        summary = _check_campaign(out, run, figures)
        keys = {"a": ["a"], "b": ["b"], "both": ["a", "b"]}[mbit]
        assert {r["mbit"] for r in summary["summary"]} >= set(keys)
        # the ROC view over the stored traces, with grids of the documented forms
        if data.draw(st.booleans(), label="eps grid form"):
            e0 = data.draw(floats(0.01, 0.5), label="eps start")
            eps = f"{e0}:{data.draw(floats(e0, 2.0), label='eps stop')}:{data.draw(floats(0.005, 0.5), label='step')}"
        else:
            eps = ",".join(str(v) for v in data.draw(st.lists(floats(0.01, 2.0), min_size=1, max_size=8)))
        counts = ",".join(str(v) for v in data.draw(st.lists(st.integers(1, 2000), min_size=1, max_size=6)))
        healthy = data.draw(floats(0.0, 50.0), label="healthy max")
        faulty = data.draw(floats(healthy, 90.0), label="faulty min")
        roc = shm("campaign-roc", "--from", out, "--eps-th", eps, "--count-max", counts, "--healthy-max-pct",
                  healthy, "--faulty-min-pct", faulty, "--json", "--out", Path(tmp) / "roc")
        doc = assert_ok(roc, json_out=True)
        assert doc["roc"] and Path(doc["files"]["roc_csv"]).exists()
        assert_readable(Path(tmp) / "roc" / "roc.png")


@examples(fast=1, fuzz_factor=0.5)
@given(n=st.integers(1, 500), seed=seeds)
@example(n=60, seed=1)  # issue 15: --n 60 --seed 1 ended "'yerr' must not contain negative values"
@example(n=40, seed=1)
def test_campaign_works_for_every_n_up_to_500(n, seed):
    """Both edges of the interval arithmetic (a range where nothing is detected and one where everything is),
    with the Fig. 11 figure drawn."""
    with tempfile.TemporaryDirectory(prefix="shm-prop-campaign-n-") as tmp:
        out = Path(tmp) / "c"
        run = shm("campaign", "--mbit", "a", "--ranges", "0-10,40-50", "--n", n, "--seed", seed, "--workers", "1",
                  "--batch-size", max(25, n // 4), "--no-progress", "--json", "--out", out)
        _check_campaign(out, run, figures=True)


if FUZZ:  # exhaustive n = 1..500 only in `make fuzz` (SHM_CLI_FUZZ=1); the figures every 25th n (~2 s each)
    @pytest.mark.parametrize("n", range(1, 501))
    def test_campaign_every_n_exhaustively(n):
        figures = n % 25 == 0 or n in (40, 60)
        with tempfile.TemporaryDirectory(prefix="shm-prop-campaign-every-n-") as tmp:
            out = Path(tmp) / "c"
            run = shm("campaign", "--mbit", "a", "--ranges", "0-10,40-50", "--n", n, "--seed", 1, "--workers", "1",
                      "--batch-size", max(25, n // 4), "--no-progress", "--json", "--out", out,
                      *([] if figures else ["--no-figures"]))
            _check_campaign(out, run, figures=figures)
