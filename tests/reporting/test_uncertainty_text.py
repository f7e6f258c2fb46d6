"""A value and its uncertainty printed with the digits the uncertainty needs (issue 27, point 2: α_h showed
"± 0.00 %")."""

from __future__ import annotations

import math
import re
from decimal import Decimal

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reporting.uncertainty_text import format_percent_change, format_uncertain

_FIXED = re.compile(r"^([+-]?\d+(?:\.(\d+))?) ± (\d+(?:\.(\d+))?)$")


def _sig_digits(text: str) -> int:
    digits = text.replace(".", "").lstrip("0")
    return len(digits)


@pytest.mark.parametrize(("value", "u", "kw", "text"), [
    (9.740123, 0.000471, {}, "9.74012 ± 0.00047"),
    (-18.1321, 0.3589, {"sign": True}, "-18.13 ± 0.36"),
    (12345.0, 234.0, {}, "12350 ± 230"),
    (5.0, 0.0996, {}, "5.00 ± 0.10"),
    (-0.0001, 0.01, {"sign": True}, "+0.000 ± 0.010"),
    (1.234e-9, 1.2e-11, {}, "(1.234 ± 0.012)e-09"),
    (3.0, None, {}, "3 ± ?"),
    (3.0, 0.0, {}, "3 ± 0"),
])
def test_known_values(value, u, kw, text):
    assert format_uncertain(value, u, **kw) == text


def test_the_alpha_h_case_of_the_report_keeps_its_digits():
    # the report printed "+9.74 ± 0.00 %" for α_h at 900 h of the aging life
    assert format_percent_change(0.0974012, 4.7e-6) == "+9.74012 ± 0.00047 %"


@settings(max_examples=400, deadline=None)
@given(value=st.floats(-1e5, 1e5, allow_nan=False), exp=st.floats(-5.9, 4.9), sig=st.integers(1, 3))
def test_the_uncertainty_sets_the_digits(value, exp, sig):
    u = 10.0 ** exp
    text = format_uncertain(value, u, sig=sig)
    m = _FIXED.match(text)
    assert m, text
    v_txt, v_dec, u_txt, u_dec = m.groups()
    # the uncertainty is never printed as zero, and carries exactly `sig` significant digits (trailing zeros of an
    # integer part are place holders when the last digit sits left of the point)
    assert float(u_txt) > 0
    if u_dec is not None:
        assert _sig_digits(u_txt) == sig, text
    # value and uncertainty end at the same decimal place
    assert len(v_dec or "") == len(u_dec or ""), text
    # both are the true numbers rounded at that place
    place = -len(u_dec) if u_dec else 0
    half = 0.5 * 10.0 ** place if u_dec else 0.5 * 10.0 ** (len(u_txt) - _sig_digits(u_txt.rstrip("0") or "0"))
    assert abs(float(Decimal(v_txt)) - value) <= half * (1 + 1e-9) + 1e-12 * abs(value)
    assert abs(float(u_txt) - u) <= half * (1 + 1e-9)
    assert abs(float(u_txt) - u) <= 0.5 * 10.0 ** (math.floor(math.log10(u)) - sig + 2)


@settings(max_examples=200, deadline=None)
@given(value=st.floats(-1e3, 1e3, allow_nan=False), exp=st.one_of(st.floats(-14, -7), st.floats(7, 12)))
def test_tiny_or_huge_uncertainties_share_a_power_of_ten(value, exp):
    u = 10.0 ** exp
    text = format_uncertain(value, u)
    m = re.match(r"^\(([+-]?\d+(?:\.\d+)?) ± (\d+(?:\.\d+)?)\)e([+-]\d+)$", text)
    assert m, text
    scale = 10.0 ** int(m.group(3))
    assert float(m.group(2)) > 0
    assert abs(float(m.group(2)) * scale - u) <= 0.051 * u
    assert abs(float(m.group(1)) * scale - value) <= u + 1e-15 * abs(value)


def test_numpy_floats_print_like_python_floats():
    import numpy as np

    assert format_uncertain(np.float64(9.743841), np.float64(0.00047), sign=True) == format_uncertain(
        9.743841, 0.00047, sign=True)
