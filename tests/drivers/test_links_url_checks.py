"""Link URLs a careless or unlucky user writes (issue 33): every malformed host, port, query value, unknown option or
scheme is an InputError naming the URL part and what is allowed — never urllib's or numpy's bare ValueError — and a
hypothesis property over random URL strings: parsing either succeeds or raises InputError, nothing else.
Parsing only: no port is opened, no rig is built."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from board_config.errors import InputError
from drivers import open_link
from drivers.link_url import network_endpoint
from hil_stub.sim_url import parse_sim_url

BAD_URLS = [
    ("modbus-tcp://[::1:5020", ["[::1:5020", "closing ']'", "[ADDRESS]:PORT"]),
    ("modbus-tcp://[::1]x", ["'x' after ']'"]),
    ("modbus-tcp://[nonsense]:502", ["[nonsense]", "not an IPv6 address"]),
    ("modbus-tcp://::1:5020", ["IPv6", "brackets"]),
    ("modbus-tcp://host:0", ["port 0", "1 .. 65535"]),
    ("modbus-tcp://host:65536", ["65536", "1 .. 65535"]),
    ("modbus-tcp://host:", ["no port"]),
    ("modbus-tcp://host:５０２", ["not a number"]),
    ("modbus-tcp://my host:502", ["'my host'", "host name or IP address"]),
    ("modbus-tcp://300.1.1.1:502", ["300.1.1.1", "IPv4"]),
    ("modbus-tcp://admin@rig:502", ["user information"]),
    ("modbus-tcp://rig:502/holding", ["/holding", "means nothing"]),
    ("modbus-tcp://rig:502?unit=nan", ["unit"]),
    ("modbus-tcp://rig:502?timeout=inf", ["timeout"]),
    ("modbus-tcp://rig:502?speed=1", ["unknown option", "speed"]),
    ("modbus-rtu:/dev/ttyUSB0?parity=X", ["parity"]),
    ("modbus-rtu:/dev/ttyUSB0?stopbits=3", ["stopbits", "[1, 2]"]),
    ("socket://[::1", ["closing ']'"]),
    ("socket://rig", ["no port"]),
    ("rfc2217://rig:99999", ["99999"]),
    ("serial:socket://rig:http", ["'http'", "not a number"]),
    ("serial:carrier://x", ["carrier://", "unknown serial URL protocol", "socket://"]),
    ("serial:/dev/ttyUSB0?speed=9600", ["speed", "unknown option", "baud"]),
    ("serial:loop://?bogus=1", ["bogus", "loop://"]),
    ("serial:/dev/ttyUSB0?baud=fast", ["baud", "not a number"]),
    ("simulator", ["unknown link URL", "known schemes"]),
    ("ftp://rig:21", ["unknown link URL"]),
]


@pytest.mark.parametrize(("url", "needles"), BAD_URLS, ids=[u for u, _ in BAD_URLS])
def test_a_bad_link_url_is_one_clear_input_error(url: str, needles: list[str]) -> None:
    with pytest.raises(InputError) as info:
        open_link(url)
    text = str(info.value)
    assert "\n" not in text and url in text
    for needle in needles:
        assert needle in text, f"{needle!r} not in {text!r}"


SIM_BAD = [
    ("sim://?seed=-1", ["seed=-1", "0 .. 2^32-1"]),
    ("sim://?seed=4294967296", ["4294967296", "0 .. 2^32-1"]),
    ("sim://?seed=1.5", ["seed", "integer"]),
    ("sim://rig?seed=1", ["'rig' after sim://"]),
    ("sim://?sede=1", ["unknown option", "sede"]),
    ("sim://?colour=", ["unknown option", "colour"]),
]


@pytest.mark.parametrize(("url", "needles"), SIM_BAD, ids=[u for u, _ in SIM_BAD])
def test_a_bad_sim_url_is_one_clear_input_error(url: str, needles: list[str]) -> None:
    with pytest.raises(InputError) as info:
        parse_sim_url(url)
    for needle in needles:
        assert needle in str(info.value)


@pytest.mark.parametrize(("url", "host", "port"), [
    ("modbus-tcp://127.0.0.1:5020?unit=1", "127.0.0.1", 5020), ("modbus-tcp://[::1]:5020", "::1", 5020),
    ("modbus-tcp://rig-01.lab.example/", "rig-01.lab.example", 502),
    ("modbus-tcp://[fe80::1%eth0]:1", "fe80::1%eth0", 1),
])
def test_good_endpoints_are_read(url: str, host: str, port: int) -> None:
    assert network_endpoint(url, "modbus-tcp://", 502) == (host, port)
    open_link(url)  # builds the link (nothing is opened)


_SCHEMES = ["modbus-tcp://", "modbus-rtu:", "socket://", "rfc2217://", "serial:", "serial:socket://",
            "serial:rfc2217://", "serial:loop://", "sim", "sim:", "sim://", ""]
_PIECES = st.sampled_from(["[", "]", ":", "::1", "?", "&", "=", "/", "@", "#", "%", "%zz", "unit", "timeout", "seed",
                           "baud", "parity", "-1", "0", "65536", "nan", "inf", "1e400", "N", "x", " ", "é", "\x00",
                           "127.0.0.1", "fc23", "handshake", "scenario", "coupling", ".", "-"])
_TAILS = st.lists(st.one_of(_PIECES, st.text(max_size=4)), max_size=10).map("".join)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scheme=st.sampled_from(_SCHEMES), tail=_TAILS)
def test_parsing_any_url_succeeds_or_says_why(scheme: str, tail: str) -> None:
    url = scheme + tail
    try:
        if url.startswith("sim") and not url.startswith(("simu",)):
            parse_sim_url(url)  # the rig itself is not built: parsing is what is tested
        else:
            open_link(url)
    except InputError as exc:
        assert str(exc).strip(), url
