"""The compiled integrators give, bit for bit, the outputs, states, bus, statuses and step counts stored in
``tests/data/integrator_reference.npz`` (written before issue 30 turned the integrators from source text into
ordinary functions; see ``tests/integrator_reference.py`` for the cases)."""

from __future__ import annotations

import numpy as np
import pytest
from integrator_reference import COMPOSITIONS, FIXTURE, INPUT_FIELDS, OUTPUT_FIELDS, model_of, run_case


@pytest.fixture(scope="module")
def stored() -> dict[str, np.ndarray]:
    with np.load(FIXTURE) as data:
        return {k: data[k] for k in data.files}


def _case_names(stored: dict[str, np.ndarray], composition: str) -> list[str]:
    return sorted({k.split("/")[1] for k in stored if k.startswith(composition + "/")})


@pytest.mark.parametrize("composition", list(COMPOSITIONS))
def test_integrators_reproduce_the_stored_runs_bit_for_bit(stored, composition):
    model = model_of(composition)
    kernels = model.kernels()
    atol = np.ascontiguousarray(model.state_scales * 1e-6)
    names = _case_names(stored, composition)
    assert len(names) >= 10
    lanes_cases = [n for n in names if stored[f"{composition}/{n}/settings"][0] == 2]
    assert lanes_cases and kernels.HAS_LANES  # both integrators are exercised
    for name in names:
        case = {k: stored[f"{composition}/{name}/{k}"] for k in INPUT_FIELDS}
        got = run_case(kernels, atol, model.n_outputs, case)
        for key in OUTPUT_FIELDS:
            want = stored[f"{composition}/{name}/{key}"]
            assert got[key].shape == want.shape, (name, key)
            # bit for bit (NaN where NaN, the sign of a zero), not merely equal
            same = np.array_equal(got[key].view(np.uint8), want.view(np.uint8))
            if not same:
                np.testing.assert_array_equal(got[key], want, err_msg=f"{composition}/{name}/{key}")
            assert same, f"{composition}/{name}/{key}: equal values but different bits"


def test_the_stored_runs_cover_every_status(stored):
    """The fixture holds every outcome of both integrators: OK, diverged, step too small, step budget."""
    for composition in COMPOSITIONS:
        for entry in (0, 2):
            codes: set[int] = set()
            for name in _case_names(stored, composition):
                if stored[f"{composition}/{name}/settings"][0] == entry:
                    codes |= {int(c) for c in stored[f"{composition}/{name}/status"] if c >= 0}
            assert codes == {0, 1, 2, 3}, (composition, entry, codes)
