"""``make setup``'s kernel step: the plant's shipped compositions (:mod:`plant.warm`) and ``shm discover``'s
dictionary, compiled once per machine into numba's cache: ``python -m workbench.warm [--jobs N] [--list]``.

``shm discover`` composes the nominal model with one generated effect holding every candidate term
(:func:`workbench.discover.dictionary_source`). Its source depends only on the terms' structure — which
signals the records move and whether the patches are driven — not on the record's values, so the kernel compiled
here is the one a first ``shm discover`` loads: the driven dictionary with the amplifier terminal and the free one
with the open circuit. It is the largest kernel of all (200+ terms: minutes to compile on a loaded machine, once).
"""

from __future__ import annotations

import inspect
import sys
from collections.abc import Sequence

from plant.warm import ShippedComposition
from plant.warm import main as plant_main
from workbench.discover import build_dictionary, dictionary_source, generated_effect

#: the peak memory of one dictionary kernel's compile (12.6 GB resident measured, 423 terms, 2026-11-29): two side by
#: side on a 24 GiB machine were killed for memory, so the warm runs as many as fit
DICTIONARY_PEAK_BYTES = 14 * 2**30
#: the signals a record's scales name (workbench.discover.signal_scales), all moving
SIGNALS = (*(f"{s}{j}" for s in ("z", "zd", "delta", "ddelta") for j in (1, 2, 3)), "vc", "va", "ic", "one", "t")


def discover_compositions() -> list[ShippedComposition]:
    """The dictionary effect of ``shm discover`` (driven and free) on the nominal model, as discover composes it."""
    out = []
    for driven, terminal in ((True, "amplifier"), (False, "open_circuit")):
        terms = build_dictionary(dict.fromkeys(SIGNALS, 1.0), driven=driven)
        cls = generated_effect(dictionary_source(terms), "dictionary_" + ("driven" if driven else "open"))
        out.append(ShippedComposition("table2", (f"{inspect.getfile(cls)}:{cls.__name__}",), terminal,
                                      peak_bytes=DICTIONARY_PEAK_BYTES))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    return plant_main(argv, extra=discover_compositions)


if __name__ == "__main__":
    sys.exit(main())
