"""The error types of the configuration layer, and the one base class of every error a user can fix.

:class:`InputError` is what the ``shm`` command line turns into ``shm: error: <message>`` with exit code 2 ("bad
usage or bad input"). Every layer raises a subclass of it (records, effects, fits, campaigns, links ...) when the
cause is a file, option or value the user gave; any other exception reaching the command line is a bug in mfc-shm
(exit 1). It lives here because this package is the bottom layer that every other one may import.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class InputError(ValueError):
    """Input the user can fix: a file, option or value. The message names it and says why it is wrong.

    A ``ValueError`` subclass so that code catching ``ValueError`` around validation keeps working. Every subclass
    pickles (whatever its ``__init__``), so one raised in a worker process reaches the parent as the same error
    with the same message, instead of breaking the pool (issue 33).
    """

    def __reduce__(self) -> tuple[Callable[..., InputError], tuple[type[InputError], str, dict[str, Any]]]:
        return (_rebuild_input_error, (type(self), str(self), dict(self.__dict__)))


def _rebuild_input_error(cls: type[InputError], message: str, state: dict[str, Any]) -> InputError:
    err = cls.__new__(cls)
    ValueError.__init__(err, message)
    err.__dict__.update(state)
    return err


class ConfigError(InputError):
    """A configuration file or value is wrong.

    The message always names the file, the key (dotted, e.g. ``parameters.k3.value``) and the reason,
    so that a user can go straight to the line to fix.
    """

    def __init__(self, file: str, key: str, reason: str) -> None:
        self.file = str(file)
        self.key = key
        self.reason = reason
        super().__init__(f"{self.file}: key '{key}': {reason}")
