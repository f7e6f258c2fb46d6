"""The one reader of link-URL options: the query of ``serial:/dev/ttyUSB0?baud=115200&timeout=0.02``,
``modbus-tcp://HOST:PORT?unit=3`` or ``sim://?scenario=degraded&seed=2``.

:func:`split_url_query` cuts a URL into its base and its ``key=value`` pairs; :class:`UrlOptions` reads the
pairs a link knows, with range checks. Every problem is an :class:`~board_config.errors.InputError` that names
the URL, the option and why.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from urllib.parse import parse_qsl

from board_config.errors import InputError


def split_url_query(url: str) -> tuple[str, list[tuple[str, str]]]:
    """``"a?x=1&y="`` → ``("a", [("x", "1"), ("y", "")])`` (percent-decoded, blank values kept, order kept)."""
    base, sep, query = url.partition("?")
    return base, (parse_qsl(query, keep_blank_values=True) if sep else [])


class UrlOptions:
    """The options of one link URL (a later ``key=`` overrides an earlier one), read with checks.

    ``url`` is the whole URL as the user wrote it; every message names it.
    """

    def __init__(self, url: str, pairs: Iterable[tuple[str, str]]) -> None:
        self.url = url
        self.values: dict[str, str] = dict(pairs)

    @classmethod
    def of(cls, url: str) -> UrlOptions:
        """The options in the query of ``url`` (after its first ``?``)."""
        return cls(url, split_url_query(url)[1])

    @classmethod
    def from_query(cls, url: str, query: str) -> UrlOptions:
        """The options in ``query`` (``a=1&b=2``, already cut from ``url``), messages naming ``url``."""
        return cls(url, parse_qsl(query, keep_blank_values=True))

    def _error(self, text: str) -> InputError:
        return InputError(f"link URL '{self.url}': {text}")

    def check_known(self, known: Collection[str]) -> None:
        """Refuse options outside ``known``, naming them and the known ones."""
        unknown = set(self.values) - set(known)
        if unknown:
            raise self._error(f"unknown option(s) {', '.join(sorted(unknown))} (known: {', '.join(sorted(known))})")

    def __contains__(self, key: str) -> bool:
        return key in self.values

    def text(self, key: str, default: str | None = None) -> str | None:
        """The option as written (``default`` when absent)."""
        return self.values.get(key, default)

    def number(self, key: str, default: float, lo: float, hi: float) -> float:
        """The option as a number in ``[lo, hi]`` (``default`` when absent, unchecked)."""
        raw = self.values.get(key)
        if raw is None:
            return default
        try:
            value = float(raw)
        except ValueError:
            raise self._error(f"option {key}={raw!r} is not a number") from None
        if not lo <= value <= hi:
            raise self._error(f"option {key}={value:g} outside the allowed range [{lo:g}, {hi:g}]")
        return value

    def integer(self, key: str, default: int, lo: float, hi: float) -> int:
        """:meth:`number`, truncated to an integer."""
        return int(self.number(key, default, lo, hi))

    def flag(self, key: str, default: bool) -> bool:
        """A 0/1 option."""
        return bool(self.number(key, int(default), 0, 1))

    def choice(self, key: str, default: str, allowed: Collection[str]) -> str:
        """The option, upper-cased, one of ``allowed`` (``default`` when absent)."""
        value = self.values.get(key, default).upper()
        if value not in allowed:
            raise self._error(f"{key}={value!r}, allowed {', '.join(allowed)}")
        return value


def split_host_port(text: str) -> tuple[str, int] | None:
    """``"HOST:PORT"`` → ``(HOST, PORT)``; ``None`` when either part is missing or the port is not digits."""
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        return None
    return host, int(port)
