"""Whether a composed kernel is already compiled on disk, and the one announcement before a compile that is not.

numba keeps each compiled function of a generated kernel module (:mod:`plant.compose`) in its on-disk cache
(``NUMBA_CACHE_DIR``): an *index* file per function, listing the compiled signatures, beside the machine code.
:func:`is_cached` reads that index (as numba itself does before compiling): a non-empty, current index means the
next call loads machine code in a fraction of a second; otherwise the call compiles, which takes tens of seconds.

Before such a compile, :func:`announce_compile` says so on stderr — "compiling the model for effects X, Y (first
use, ~N s) …" — so that no command sits silent while numba works. A warm start prints nothing. The announcer can be
swapped (:func:`set_announcer`) by a caller that owns the terminal (a progress bar writes it through itself).
``make setup`` builds the shipped compositions ahead of time (:mod:`plant.warm`), so a fresh clone's first
command is warm.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

#: numba's on-disk cache when the environment names none: the Makefile's default, so that the kernels ``make setup``
#: compiled serve a later ``shm`` typed in a shell that never exported ``NUMBA_CACHE_DIR`` (numba would otherwise
#: cache beside the generated modules, in another directory, and compile again)
DEFAULT_CACHE_DIR = os.path.join(os.path.expanduser("~"), ".cache", "mfc-shm", "numba")


def use_default_cache_dir() -> None:
    """Point numba at :data:`DEFAULT_CACHE_DIR` unless ``NUMBA_CACHE_DIR`` is set (before or after numba loaded)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    os.environ["NUMBA_CACHE_DIR"] = DEFAULT_CACHE_DIR
    config = getattr(sys.modules.get("numba"), "config", None)
    if config is not None and not getattr(config, "CACHE_DIR", ""):
        config.CACHE_DIR = DEFAULT_CACHE_DIR


use_default_cache_dir()  # at import: plant imports this module before anything that loads numba

#: rough compile time (s) of a composition's entry points: the first entry point of a module (``run_chunk``:
#: integrator, right-hand side, outputs) and the lane integrator (``run_lanes``); each effect beyond the nominal
#: ones adds its hooks. Measured with numba 0.68 on the shared 2-core development machine at load 5-8: run_chunk
#: 9-17 s, run_lanes 30-50 s (about half that on an idle core).
ENTRY_BASE_S = {"run_chunk": 12.0, "run_lanes": 40.0}
PER_EFFECT_S = {"run_chunk": 1.0, "run_lanes": 3.0}
#: and per 1000 characters of an extra effect's hook source beyond the first (shm discover's dictionary, ~40 000
#: characters of generated hooks, compiled for ~290 s at load 8)
PER_HOOK_KCHAR_S = 6.0


def _print_stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


_announcer: Callable[[str], None] = _print_stderr


def set_announcer(fn: Callable[[str], None]) -> Callable[[str], None]:
    """Route compile announcements to ``fn`` (one line of text each); returns the previous announcer."""
    global _announcer
    previous, _announcer = _announcer, fn
    return previous


def is_cached(dispatcher: Any) -> bool:
    """True when ``dispatcher`` (a numba function) is compiled in this process or has a current entry in numba's
    on-disk cache; False when calling it would compile (no cache, an empty or stale index)."""
    if getattr(dispatcher, "signatures", None):
        return True
    cache = getattr(dispatcher, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    if cache_file is None:  # caching disabled (a composition compiled in memory): always compiles
        return False
    try:
        return bool(cache_file._load_index())
    except Exception:  # an unreadable index: numba will compile
        return False


def estimate_s(entry: str, n_extra: int, hook_chars: int = 0) -> float:
    """Rough compile time (s) of ``entry`` for the nominal model with ``n_extra`` more effects whose hooks have
    ``hook_chars`` characters of source in all."""
    base = ENTRY_BASE_S.get(entry, ENTRY_BASE_S["run_chunk"])
    per = PER_EFFECT_S.get(entry, PER_EFFECT_S["run_chunk"])
    bulk = max(0.0, hook_chars / 1000 - n_extra) * PER_HOOK_KCHAR_S
    return base + per * max(0, n_extra) + bulk


def hook_chars(classes: Sequence[Any]) -> int:
    """Characters of hook source of the extra effects (role ``effect``) in ``classes``; 0 where it is unknown."""
    from plant.effect import hook_function

    n = 0
    for cls in classes:
        if getattr(cls, "role", "") != "effect":
            continue
        for hook in ("pre", "rates", "post", "output"):
            fn = hook_function(cls, hook)
            try:
                n += len(inspect.getsource(fn)) if fn is not None else 0
            except (OSError, TypeError):
                continue
    return n


def composition_words(classes: Sequence[Any]) -> tuple[str, int]:
    """(the composition in words — its effects beyond the core, the core when it is not the nominal one, its
    terminal —, how many effects beyond the core) for effect classes with ``name`` and ``role``."""
    from plant.effects import NOMINAL_EFFECTS

    core = [c.name for c in classes if c.role == "core"]
    extra = [c.name for c in classes if c.role == "effect"]
    terminal = [c.name for c in classes if c.role == "terminal"]
    parts = [] if tuple(core) == NOMINAL_EFFECTS else [f"core {', '.join(core) or 'none'}"]
    parts += [f"{', '.join(terminal)} terminal"] if terminal else []
    what = f"the model for effects {', '.join(extra)}" if extra else "the nominal model"
    return f"{what} ({'; '.join(parts)})" if parts else what, len(extra)


def compile_message(words: str, entry: str, seconds: float) -> str:
    """The announcement's text: which model, that it is the first use, and how long it will take."""
    part = "" if entry == "run_chunk" else " — its batch integrator (lanes)"
    return f"compiling {words}{part} (first use, ~{seconds:.0f} s; cached afterwards) …"


def announce_compile(classes: Sequence[Any], entry: str = "run_chunk") -> None:
    """Say, before it starts, that ``entry`` of the composition of effect ``classes`` is about to compile."""
    words, n_extra = composition_words(classes)
    _announcer(compile_message(words, entry, estimate_s(entry, n_extra, hook_chars(classes))))
