"""The ``sim`` link URL: ``sim``, ``sim:NAME`` or ``sim://?scenario=NAME|PATH&seed=S&params=P&coupling=C``."""

from __future__ import annotations

from dataclasses import dataclass

from board_config.errors import InputError
from board_config.url_options import UrlOptions, split_url_query

SIM_URL_OPTIONS = ("scenario", "seed", "params", "coupling")


@dataclass(frozen=True)
class SimUrl:
    """The options of a ``sim`` URL (``None``: not given or blank)."""

    scenario: str | None = None  # a shipped scenario name or a TOML path
    seed: int | None = None
    params: str | None = None
    coupling: str | None = None


def parse_sim_url(url: str) -> SimUrl:
    """The options of ``url`` (a ``scenario`` option wins over ``sim:NAME``); :class:`InputError` naming the URL for
    an unknown option or a non-integer seed."""
    base, pairs = split_url_query(url)
    rest = base[3:] if base.startswith("sim") else base
    name = rest[1:] or None if rest.startswith(":") and not rest.startswith("://") else None
    opts = UrlOptions(url, [(k, v) for k, v in pairs if v])  # a blank option counts as not given
    opts.check_known(SIM_URL_OPTIONS)
    seed = None
    raw = opts.text("seed")
    if raw is not None:
        try:
            seed = int(raw)
        except ValueError:
            raise InputError(f"sim link URL {url!r}: seed must be an integer, got {raw!r}") from None
    return SimUrl(scenario=opts.text("scenario", name), seed=seed, params=opts.text("params"),
                  coupling=opts.text("coupling"))
