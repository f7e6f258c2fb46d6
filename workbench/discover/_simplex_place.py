"""Instants and sizes of a kept change moved together on the whole record's error: a simplex search (issue 26
point 3).

A refit on the training blocks moves sizes and instants by their gradient from where a zoom left them, and the
zooms move one thing at a time; on a sweep the two trade (a step placed late is sized larger), and the error has
narrow valleys between the sweep's passes through a resonance. Root losing 25 % at 4.5 s of a 15 s sweep and
getting 15 % back at 9.75 s: the two steps, each onset placed in turn and the sizes refitted with them held, stayed
at 22.3 % at 4.440 s and 12.2 % at 9.893 s (10.7 σ held out). A Nelder–Mead simplex walks such valleys with every
coordinate at once; its probes are whole-record simulations of a few tens of milliseconds, so a few hundred cost
seconds. The onsets it finds are placed on the whole record, as :mod:`workbench.discover._onset_profile` places
them; the caller refits the sizes on the training blocks with the onsets held, so the held-out error stays honest.

Pure logic on the fit engine's objects (SciPy's ``minimize``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import minimize

from plant import PlantModel
from workbench.discover._finite_change import whole_scores
from workbench.discover._onset import MAX_LOSS
from workbench.fit import Target

#: at most this many probes (whole-record simulations of every record) per simplex search
SIMPLEX_EVALS = 400
#: the simplex stops when its points are this close (in the parameters' units: seconds, shares) and their errors
#: this close (σ)
SIMPLEX_XTOL = 1e-4
SIMPLEX_FTOL = 1e-4


def simplex_search(rms: Callable[[list[float]], float], x0: Sequence[float], max_evals: int = SIMPLEX_EVALS
                   ) -> tuple[list[float], float]:
    """The point a Nelder–Mead simplex reaches from ``x0`` on ``rms`` (inf outside the allowed region) within
    ``max_evals`` evaluations, and its value (``x0`` and inf when it starts outside)."""
    if not math.isfinite(rms(list(map(float, x0)))):
        return list(map(float, x0)), math.inf
    with np.errstate(invalid="ignore"):  # vertices outside the region compare inf with inf
        out = minimize(lambda x: rms([float(v) for v in x]), np.asarray(x0, float), method="Nelder-Mead",
                       options={"maxfev": max_evals - 1, "xatol": SIMPLEX_XTOL, "fatol": SIMPLEX_FTOL})
    return [float(v) for v in out.x], float(out.fun)


def placed_together(targets: Sequence[Target], models: Sequence[PlantModel], values: dict[str, float],
                    onsets: Sequence[str], sizes: Sequence[str], span: tuple[float, float], threads: int | None,
                    max_evals: int = SIMPLEX_EVALS) -> tuple[dict[str, float], float, int]:
    """``values`` with the ``onsets`` (s, kept within ``span``) and the relative ``sizes`` (a loss never past
    ``MAX_LOSS``) moved together by :func:`simplex_search` on the whole record's RMS, every other value held.
    Returns the values, their whole-record RMS (σ) and the simulations run."""
    names = [*onsets, *sizes]
    n = 0

    def rms(x: list[float]) -> float:
        nonlocal n
        setting = dict(zip(names, x))
        if any(not span[0] <= setting[g] <= span[1] for g in onsets) or any(setting[c] < MAX_LOSS for c in sizes):
            return math.inf
        n += 1
        return whole_scores(targets, models, values, [setting], threads)[0]

    x, score = simplex_search(rms, [float(values[k]) for k in names], max_evals)
    return values | dict(zip(names, x)), score, n * len(targets)
