"""Two changes in two places at once, screened together (issue 26 point 3): the held-out linear screen of every
*pair* of dictionary terms (:func:`pair_screen`), where forward selection screens one term at a time.

Why it is needed: two patches weak in opposite polarities — the root patch 35 % weaker while its voltage is
positive, the tip patch while its voltage is negative — on a 15 s sweep. Each weakness alone halves one patch's
authority on average and adds an even harmonic; together their averages look like one lower gain. Round 1 kept a
laser gain 11.5 % low (178 → 15.8 σ: the average), and no single term added to it removes a quarter of what is left
(the even harmonics of the two patches partly cancel), so the search stopped there. The two patches' own switches,
fitted together, are the record's physics; one at a time neither is first.

The screen is the same least squares as the single screen (:func:`workbench.discover._rounds.linear_screen`), on the
same training and held-out blocks, for each pair (i, j) of terms in different places: the 2 × 2 normal equations
from the Gram matrices of the sensitivities, the held-out sum of squares from theirs — no simulation. Pure NumPy;
:mod:`workbench.discover._pair_refit` refits the best pairs on the full model.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import numpy as np

#: pairs whose two sensitivities are this correlated (|r| on the training blocks) are not screened: two near-twins
#: fitted together cancel each other with large opposite coefficients the full model does not follow
MAX_CORRELATION = 0.99


@dataclass(frozen=True)
class ScreenMatrices:
    """The current model's residuals on the training and held-out blocks (σ, flattened over targets and channels)
    and each candidate's sensitivity per unit coefficient on them (one row per candidate)."""

    r_train: np.ndarray
    r_held: np.ndarray
    x_train: np.ndarray
    x_held: np.ndarray


@dataclass(frozen=True)
class PairRow:
    """A pair of candidates (rows ``i`` < ``j`` of the matrices), their coefficients fitted together on the training
    blocks and the held-out RMS (σ) they leave."""

    i: int
    j: int
    coef_i: float
    coef_j: float
    held_rms_sigma: float


def screen_matrices(targets: Sequence, ys: Sequence[np.ndarray], eps: np.ndarray) -> ScreenMatrices:
    """The screen's matrices from a sensitivity batch: ``ys[t]`` the measured channels of target t (member 0 the
    current model, member k + 1 candidate k switched on by ``eps[k]``; shape members × channels × samples)."""
    r_tr: list[np.ndarray] = []
    r_he: list[np.ndarray] = []
    x_tr: list[np.ndarray] = []
    x_he: list[np.ndarray] = []
    for tg, y in zip(targets, ys):
        for mask, rr, xx in ((tg.train, r_tr, x_tr), (tg.held, r_he, x_he)):
            meas = tg.measured[:, mask] / tg.sigma[:, None]
            y0 = y[0][:, mask] / tg.sigma[:, None]
            rr.append((meas - y0).ravel())
            sens = (y[1:, :, :][:, :, mask] - y[0][None, :, mask]) / tg.sigma[None, :, None]
            xx.append(sens.reshape(sens.shape[0], -1) / eps[:, None])
    return ScreenMatrices(np.concatenate(r_tr), np.concatenate(r_he), np.concatenate(x_tr, axis=1),
                          np.concatenate(x_he, axis=1))


def single_held(m: ScreenMatrices, usable: np.ndarray) -> np.ndarray:
    """Each candidate's held-out RMS (σ) alone, fitted on the training blocks (inf where not ``usable``)."""
    g = np.einsum("ij,ij->i", m.x_train, m.x_train)
    b = m.x_train @ m.r_train
    ok = usable & (g > 0) & np.isfinite(g)
    a = np.where(ok, b / np.where(ok, g, 1.0), 0.0)
    resid = m.r_held[None, :] - a[:, None] * m.x_held
    out = np.sqrt(np.mean(resid * resid, axis=1))
    return np.where(ok, out, np.inf)


def pair_screen(m: ScreenMatrices, places: Sequence[Hashable], usable: np.ndarray, coef_cap: np.ndarray,
                n_best: int) -> list[PairRow]:
    """The ``n_best`` pairs of usable candidates in different ``places`` that leave the least held-out RMS, their
    coefficients fitted together on the training blocks; a pair is skipped when its sensitivities are near-collinear
    (:data:`MAX_CORRELATION`) or a coefficient exceeds its ``coef_cap`` (a relative change beyond −100 %)."""
    n_he = m.r_held.size
    g = m.x_train @ m.x_train.T
    b = m.x_train @ m.r_train
    h_mat = m.x_held @ m.x_held.T
    h = m.x_held @ m.r_held
    rr = float(m.r_held @ m.r_held)
    gd = np.diag(g).copy()
    det = gd[:, None] * gd[None, :] - g * g
    with np.errstate(divide="ignore", invalid="ignore"):
        ci = (gd[None, :] * b[:, None] - g * b[None, :]) / det
        cj = (gd[:, None] * b[None, :] - g * b[:, None]) / det
        corr2 = g * g / (gd[:, None] * gd[None, :])
        ss = (rr - 2.0 * (ci * h[:, None] + cj * h[None, :]) + ci * ci * np.diag(h_mat)[:, None]
              + 2.0 * ci * cj * h_mat + cj * cj * np.diag(h_mat)[None, :])
    ids: dict[Hashable, int] = {}
    key = np.array([ids.setdefault(p, len(ids)) for p in places])
    ok = (np.triu(np.ones_like(g, dtype=bool), 1) & usable[:, None] & usable[None, :]
          & (key[:, None] != key[None, :]) & (corr2 < MAX_CORRELATION ** 2) & np.isfinite(ss)
          & (np.abs(ci) <= coef_cap[:, None]) & (np.abs(cj) <= coef_cap[None, :]) & (det > 0))
    flat = np.flatnonzero(ok)
    order = flat[np.argsort(ss.ravel()[flat], kind="stable")][:n_best]
    rows = []
    for f in order:
        i, j = divmod(int(f), g.shape[0])
        rows.append(PairRow(i, j, float(ci[i, j]), float(cj[i, j]), float(np.sqrt(max(ss[i, j], 0.0) / n_he))))
    return rows
