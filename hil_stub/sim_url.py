"""The ``sim`` link URL: ``sim``, ``sim:NAME`` or ``sim://?scenario=NAME|PATH&seed=S&params=P&coupling=C``."""

from __future__ import annotations

from dataclasses import dataclass

from board_config.errors import InputError
from board_config.url_options import UrlOptions, split_url_query

SIM_URL_OPTIONS = ("scenario", "seed", "params", "coupling")
SEED_MAX = 2**32 - 1  #: seeds are 0 .. 2^32-1, as numpy's and `shm run --seed`


@dataclass(frozen=True)
class SimUrl:
    """The options of a ``sim`` URL (``None``: not given or blank)."""

    scenario: str | None = None  # a shipped scenario name or a TOML path
    seed: int | None = None
    params: str | None = None
    coupling: str | None = None


def parse_sim_url(url: str) -> SimUrl:
    """The options of ``url`` (a ``scenario`` option wins over ``sim:NAME``); :class:`InputError` naming the URL for
    a host or path after ``sim://``, an unknown option (also a blank one) or a seed that is not an integer in
    0 .. 2^32-1 (the range of ``shm run --seed``)."""
    base, pairs = split_url_query(url)
    rest = base[3:] if base.startswith("sim") else base
    if rest.startswith("://") and rest[3:]:
        raise InputError(f"link URL '{url}': '{rest[3:]}' after sim:// means nothing (expected sim, sim:NAME or "
                         f"sim://?{'&'.join(k + '=...' for k in SIM_URL_OPTIONS)})")
    name = rest[1:] or None if rest.startswith(":") and not rest.startswith("://") else None
    UrlOptions(url, pairs).check_known(SIM_URL_OPTIONS)  # a blank unknown option is a typo too
    opts = UrlOptions(url, [(k, v) for k, v in pairs if v])  # a blank known option counts as not given
    seed = None
    raw = opts.text("seed")
    if raw is not None:
        try:
            seed = int(raw)
        except ValueError:
            raise InputError(f"sim link URL {url!r}: seed must be an integer, got {raw!r}") from None
        if not 0 <= seed <= SEED_MAX:
            raise InputError(f"sim link URL {url!r}: seed={seed} outside the allowed range 0 .. 2^32-1")
    return SimUrl(scenario=opts.text("scenario", name), seed=seed, params=opts.text("params"),
                  coupling=opts.text("coupling"))
