"""The one-of-each text helpers of board_config (issue 13.5): TOML writer, NAME=VALUE parser, URL options, G0."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config import load_parameter_set
from board_config.assignments import parse_assignments
from board_config.errors import InputError
from board_config.physical_constants import G0
from board_config.toml_writer import toml_document, toml_key, toml_string, toml_value
from board_config.url_options import UrlOptions, split_host_port, split_url_query

_text = st.text(max_size=8)
_scalar = st.one_of(st.booleans(), st.integers(-(2**63), 2**63 - 1), st.floats(), _text)
_value = st.recursive(_scalar, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                       st.dictionaries(_text, inner, max_size=3)), max_leaves=8)
_document = st.dictionaries(_text, st.one_of(_value, st.lists(st.dictionaries(_text, _value, max_size=3), min_size=1,
                                                              max_size=2)), max_size=5)


def _same(a, b) -> bool:
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    if isinstance(a, (list, tuple)):
        return isinstance(b, list) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b and type(a) is type(b)


@settings(max_examples=300, deadline=None)
@given(_document)
def test_toml_document_reads_back_as_written(doc):
    assert _same(doc, tomllib.loads(toml_document(doc)))


def test_toml_values_and_keys():
    assert toml_value(np.float64(0.1)) == "0.1" and toml_value(np.int32(-3)) == "-3" and toml_value(True) == "true"
    assert [toml_value(x) for x in (math.nan, math.inf, -math.inf)] == ["nan", "inf", "-inf"]
    assert toml_string('a"b\\c\nd\te\x01') == '"a\\"b\\\\c\\nd\te\\u0001"'
    assert toml_key("k3") == "k3" and toml_key("a.b") == '"a.b"' and toml_key("") == '""' and toml_key("é") == '"é"'
    with pytest.raises(TypeError, match="cannot write"):
        toml_value(object())


@pytest.mark.parametrize("name", ["table2", "calibrated"])
def test_parameter_set_text_is_stable(name):
    """The serialised set is hashed by campaign stores and caches: its text must not drift."""
    text = load_parameter_set(name).to_toml()
    assert text.startswith("[meta]\nname = ") and "\n[parameters]\nR_ep = { value = " in text
    assert tomllib.loads(text)["parameters"]["k3"]["unit"] == "N/m"


def test_assignments():
    assert parse_assignments("--noise", ["z3=2e-6, v_patch=0.1", "z3=1e-6"]) == {"z3": 1e-6, "v_patch": 0.1}
    assert parse_assignments("--set", ["k3=1"], comma_lists=False) == {"k3": 1.0}
    with pytest.raises(InputError, match=r"--set 'k3=1,k2=2': '1,k2=2' is not a number"):
        parse_assignments("--set", ["k3=1,k2=2"], comma_lists=False)
    with pytest.raises(InputError, match=r"--set '': expected NAME=VALUE"):
        parse_assignments("--set", [""], comma_lists=False)
    with pytest.raises(InputError, match=r"--noise '=1': expected NAME=VALUE"):
        parse_assignments("--noise", ["=1"])
    assert parse_assignments("--noise", None) == {}


def test_url_options():
    assert split_url_query("serial:/dev/x?baud=9600&x=&baud=19200") == (
        "serial:/dev/x", [("baud", "9600"), ("x", ""), ("baud", "19200")])
    opts = UrlOptions.of("modbus-rtu:/dev/x?baud=19200&parity=e&handshake=0")
    assert opts.integer("baud", 115200, 300, 4e6) == 19200 and opts.choice("parity", "N", ("N", "E", "O")) == "E"
    assert opts.flag("handshake", True) is False and opts.number("timeout", 0.008, 1e-4, 60) == 0.008
    with pytest.raises(InputError, match=r"link URL 'modbus-rtu:/dev/x\?baud=19200&parity=e&handshake=0': unknown "
                                         r"option\(s\) baud, handshake, parity \(known: unit\)"):
        opts.check_known({"unit"})
    with pytest.raises(InputError, match=r"option baud=19200 outside the allowed range \[300, 9600\]"):
        opts.number("baud", 0, 300, 9600)
    with pytest.raises(InputError, match=r"option t='x' is not a number"):
        UrlOptions.of("u?t=x").number("t", 0, 0, 1)
    with pytest.raises(InputError, match=r"parity='X', allowed N, E, O"):
        UrlOptions.of("u?parity=x").choice("parity", "N", ("N", "E", "O"))
    assert split_host_port("127.0.0.1:0") == ("127.0.0.1", 0)
    assert split_host_port("host") is None and split_host_port(":5") is None and split_host_port("h:x") is None


def test_one_g0():
    import plant
    import plant.signals
    import workbench.records._units

    assert G0 == 9.80665 and plant.G0 is G0 and plant.signals.G0 is G0 and workbench.records._units.G0 is G0
