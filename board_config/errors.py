"""The one error type of the configuration layer."""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration file or value is wrong.

    The message always names the file, the key (dotted, e.g. ``parameters.k3.value``) and the reason,
    so that a user can go straight to the line to fix.
    """

    def __init__(self, file: str, key: str, reason: str) -> None:
        self.file = str(file)
        self.key = key
        self.reason = reason
        super().__init__(f"{self.file}: key '{key}': {reason}")
