"""Hardware-link layer: the ``Link`` protocol and its implementations. Imports only board_config."""

from drivers import hardware_links as _hardware_links  # noqa: F401  (registers serial/socket/Modbus URLs)
from drivers.link import (
    FLAG_LIMIT_REFUSED,
    FLAG_RIG_FAULT,
    FLAG_SENSOR_FAULT,
    ActuatorCommand,
    Link,
    LinkError,
    RigEndpoint,
    RigSample,
    open_link,
    register_link_scheme,
    registered_schemes,
)

__all__ = [
    "FLAG_LIMIT_REFUSED",
    "FLAG_RIG_FAULT",
    "FLAG_SENSOR_FAULT",
    "ActuatorCommand",
    "Link",
    "LinkError",
    "RigEndpoint",
    "RigSample",
    "open_link",
    "register_link_scheme",
    "registered_schemes",
]
