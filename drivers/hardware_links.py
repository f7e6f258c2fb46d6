"""URL schemes of the hardware links, registered with :func:`drivers.register_link_scheme`.

The factories import their module on first use, so ``import drivers`` stays cheap (no pyserial or pymodbus
until a hardware URL is opened).

=====================  ==========================================  =============================
scheme                 example                                     implementation
=====================  ==========================================  =============================
``serial:``            ``serial:/dev/ttyUSB0?baud=115200``         :class:`~drivers.serial_link.SerialLink`
``socket://``          ``socket://127.0.0.1:7000``                 SerialLink over raw TCP
``rfc2217://``         ``rfc2217://host:2217``                     SerialLink over RFC 2217
``modbus-tcp://``      ``modbus-tcp://127.0.0.1:5020?unit=1``      :class:`~drivers.modbus_link.ModbusLink`
``modbus-rtu:``        ``modbus-rtu:/dev/ttyUSB1?baud=115200``     ModbusLink over RTU
=====================  ==========================================  =============================
"""

from __future__ import annotations

from board_config.url_options import split_url_query
from drivers.link import Link, LinkFactory, register_link_scheme
from drivers.link_url import check_serial_target, network_endpoint

#: pyserial URL handlers this project registers itself (``hil_stub.protocol_ptymaster``)
_OWN_SERIAL_PROTOCOLS = frozenset({"ptymaster"})


def _serial_link(url: str, **_defaults: object) -> Link:
    from drivers.serial_link import SerialLink, split_link_options

    # a malformed //HOST:PORT, an unknown protocol or option is refused here, not when pyserial opens the port
    target = url.removeprefix("serial:")
    _, theirs = split_url_query(split_link_options(target)[0])
    check_serial_target(url, target, [key for key, _ in theirs], _OWN_SERIAL_PROTOCOLS)
    return SerialLink(url)


def _modbus_link(url: str, **_defaults: object) -> Link:
    from drivers.modbus_link import ModbusLink

    if url.startswith("modbus-tcp://"):
        network_endpoint(url, "modbus-tcp://", 502)  # urllib's bare ValueError ('Invalid IPv6 URL') never reached
    return ModbusLink(url)


HARDWARE_SCHEMES: dict[str, LinkFactory] = {
    "serial:": _serial_link,
    "socket://": _serial_link,
    "rfc2217://": _serial_link,
    "modbus-tcp://": _modbus_link,
    "modbus-rtu:": _modbus_link,
}

for _scheme, _factory in HARDWARE_SCHEMES.items():
    register_link_scheme(_scheme, _factory)
