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

from drivers.link import Link, LinkFactory, register_link_scheme


def _serial_link(url: str, **_defaults: object) -> Link:
    from drivers.serial_link import SerialLink

    return SerialLink(url)


def _modbus_link(url: str, **_defaults: object) -> Link:
    from drivers.modbus_link import ModbusLink

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
