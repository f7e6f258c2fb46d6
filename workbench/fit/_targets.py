"""Records cut into training and held-out parts for fitting (see :mod:`workbench.fit`).

Each record is cut into ``n_blocks`` contiguous blocks; even blocks train, odd blocks are held out
(``holdout="blocks"``), or with several records every second record is held out whole (``holdout="records"``).
Channels are scaled by their noise level σ (record metadata, else a robust estimate from the data); long records
are sub-sampled to at most ``max_rate_Hz``. :func:`model_factory` builds the per-record model (cached by terminal).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from board_config import ParameterSet
from board_config.errors import InputError
from plant import InputSignals, PhysicalEffect, PlantModel
from workbench.records import FrfRecord, Record
from workbench.simulation import estimate_noise_std, model_output_for

#: a sub-sampled record keeps at most this rate for fitting (Hz)
DEFAULT_MAX_RATE_HZ = 250.0
DEFAULT_BLOCKS = 10
#: every training and every held-out block must hold at least this many (sub-sampled) samples
MIN_BLOCK_SAMPLES = 25


class FitError(InputError):
    """Fitting cannot start or cannot proceed (bad records, bad effect, a user effect producing NaN, ...)."""


@dataclass
class Target:
    """One record prepared for fitting: the samples used, the measured channels in σ units, the split."""

    record: Record
    model: PlantModel
    inputs: InputSignals
    sample_idx: np.ndarray
    t: np.ndarray
    channels: tuple[str, ...]
    outputs: tuple[str, ...]
    units: tuple[str, ...]
    sigma: np.ndarray  # (n_ch,) SI noise level per channel
    sigma_source: tuple[str, ...]
    measured: np.ndarray  # (n_ch, n_t) SI
    train: np.ndarray  # (n_t,) bool
    held: np.ndarray  # (n_t,) bool

    @property
    def name(self) -> str:
        return self.record.name

    def out_idx(self, model: PlantModel) -> np.ndarray:
        return np.array([model.output_names.index(o) for o in self.outputs])


def _check_record(rec: Any) -> Record:
    if isinstance(rec, FrfRecord):
        raise FitError(f"{rec.path}: a frequency-response table cannot be replayed in the time domain for fitting; "
                       "give time records (mfc-shm-record/1)")
    if not isinstance(rec, Record):
        raise FitError(f"expected a measurement record, got {type(rec).__name__}")
    if not rec.outputs:
        raise FitError(f"{rec.path}: the record has no measured output channel to fit")
    return rec


def block_masks(n: int, n_blocks: int) -> tuple[np.ndarray, np.ndarray]:
    """(train, held) boolean masks of ``n`` samples cut into ``n_blocks`` contiguous blocks (even train)."""
    edges = np.linspace(0, n, n_blocks + 1).round().astype(int)
    train = np.zeros(n, bool)
    held = np.zeros(n, bool)
    for b in range(n_blocks):
        (train if b % 2 == 0 else held)[edges[b]:edges[b + 1]] = True
    return train, held


def prepare_targets(records: Sequence[Record | FrfRecord], model_for_record: Callable[[Record], PlantModel], *,
                    holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS,
                    max_rate_Hz: float = DEFAULT_MAX_RATE_HZ) -> list[Target]:
    """Cut records into training/held-out parts (see the module docstring); errors name record and reason (a
    frequency-response table, as :func:`workbench.records.load_record` may return, is refused)."""
    if not records:
        raise FitError("no records given")
    if holdout not in ("blocks", "records"):
        raise FitError(f"holdout must be 'blocks' or 'records', got {holdout!r}")
    if holdout == "records" and len(records) < 2:
        raise FitError("holdout 'records' needs at least two records (every second one is held out); "
                       "give more records or use holdout 'blocks'")
    if n_blocks < 2 or n_blocks % 2:
        raise FitError(f"n_blocks must be an even number >= 2, got {n_blocks}")
    targets = []
    for k, raw in enumerate(records):
        rec = _check_record(raw)
        model = model_for_record(rec)
        stride = max(1, math.floor(rec.sample_rate_Hz / max_rate_Hz + 1e-9))
        idx = np.arange(0, rec.n_samples, stride)
        n = idx.size
        if holdout == "blocks":
            need = n_blocks * MIN_BLOCK_SAMPLES
            if n < need:
                raise FitError(
                    f"{rec.path}: too short to hold out: {rec.n_samples} samples ({rec.duration_s:.3g} s; {n} after "
                    f"sub-sampling to ≤ {max_rate_Hz:g} Hz) but {n_blocks} blocks of at least {MIN_BLOCK_SAMPLES} "
                    f"samples each need {need}; give a longer record, several records with holdout 'records', "
                    "or fewer blocks")
            train, held = block_masks(n, n_blocks)
        else:
            if n < 2 * MIN_BLOCK_SAMPLES:
                raise FitError(f"{rec.path}: too short: {n} samples, at least {2 * MIN_BLOCK_SAMPLES} needed")
            train = np.full(n, k % 2 == 0)
            held = ~train
        channels = tuple(rec.outputs)
        outputs = tuple(model_output_for(model, rec.path, c, rec.channels[c].model_output) for c in channels)
        meas = np.vstack([rec[c][idx] for c in channels])
        sig, src = [], []
        for c in channels:
            ch = rec.channels[c]
            if ch.noise_std is not None and ch.noise_std > 0:
                s, how = float(ch.noise_std), "record metadata noise_std"
            else:
                s, how = estimate_noise_std(rec[c]), "estimated from the data (MAD of second differences)"
            floor = 1e-6 * max(float(np.ptp(rec[c])), 1e-300)
            if not s > floor:
                s, how = floor, "floor: 1e-6 of the channel's range (noise-free data)"
            sig.append(s)
            src.append(how)
        targets.append(Target(
            record=rec, model=model, inputs=rec.input_signals(), sample_idx=idx, t=rec.t[idx].copy(),
            channels=channels, outputs=outputs, units=tuple(rec.channels[c].si_unit for c in channels),
            sigma=np.array(sig), sigma_source=tuple(src), measured=meas, train=train, held=held))
    if not any(t.train.any() for t in targets) or not any(t.held.any() for t in targets):
        raise FitError("the split leaves no training or no held-out samples")
    return targets


def model_factory(params: ParameterSet, effects: Sequence[type[PhysicalEffect]]):
    """A per-record model builder (cached by terminal)."""
    cache: dict[str, PlantModel] = {}

    def build(rec: Record) -> PlantModel:
        terminal = rec.terminal or ("open_circuit" if rec.drive()[0] == "z0dd" else "amplifier")
        if terminal not in cache:
            cache[terminal] = PlantModel(params, effects=list(effects), terminal=terminal)
        return cache[terminal]

    return build
