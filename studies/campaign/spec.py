"""What a Monte-Carlo MBIT campaign is: deviation ranges, random draws, batches, and the settings that fix them.

Degraded hardware (seed Sec. 4.2, steps i–ii)
---------------------------------------------
A unit of range ``[lo, hi)`` (fractions; 10–20 % is ``lo=0.1, hi=0.2``) is the nominal parameter set with each
deviated parameter ``p`` (default ``k3``, ``alpha_h``, ``beta_h``) replaced by ``p_nom * (1 + s * u)``:

* ``u`` uniform in ``[lo, hi)``, independently per parameter (the *magnitude* of the relative deviation);
* ``s`` the sign convention: ``"both"`` (default) — ``+1`` or ``−1`` with probability 1/2 each, independently per
  parameter, i.e. the deviation is uniform over ``(−hi, −lo] ∪ [lo, hi)``; ``"minus"`` — always −1 (a laminate
  that lost stiffness / hysteresis coefficients); ``"plus"`` — always +1.

Seeding and reproducibility
---------------------------
Run ``i`` of range ``[lo, hi)`` draws from its own ``numpy.random.SeedSequence(seed, spawn_key=(lo_bp, hi_bp, i))``
(``lo_bp``/``hi_bp`` are the bounds in basis points) — the child that ``SeedSequence(seed).spawn`` would give at
that key. So a run's hardware does not depend on the batch it lands in, the number or kind of workers, the other
ranges requested or ``--n`` (run 7 of 10–20 % is the same unit in a 10-run and a 100-run campaign), and each
batch integrates its members independently (per-trajectory step control): results are bit-for-bit identical
whatever the execution. Optional measurement noise uses a separate child per run and MBIT.
"""

from __future__ import annotations

import hashlib
import json
import math
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from board_config import CORE_SCHEMA, MbitDefinition, MonitorSettings
from board_config.errors import InputError

SIGN_CONVENTIONS = ("both", "minus", "plus")
DEFAULT_DEVIATED: tuple[str, ...] = ("k3", "alpha_h", "beta_h")
#: default runs per batch (one task for a worker; ~15 ms task overhead on Dask is negligible against it)
DEFAULT_BATCH_SIZE = 25
#: layout version of the stored batch files (bump when their content changes)
STORE_VERSION = 1


@dataclass(frozen=True)
class DeviationRange:
    """Relative deviation magnitudes in ``[lo, hi)`` (fractions, 0.1 = 10 %)."""

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and 0.0 <= self.lo < self.hi):
            raise InputError(f"deviation range must satisfy 0 <= lo < hi, got lo={self.lo!r}, hi={self.hi!r}")

    @property
    def key(self) -> tuple[int, int]:
        """Bounds in basis points (0.01 %), used in seeds and file names."""
        return round(self.lo * 10_000), round(self.hi * 10_000)

    @property
    def label(self) -> str:
        return f"{self.lo * 100:g}-{self.hi * 100:g}%"


#: most deviation ranges one campaign takes (each is a class of degraded units with its own statistics)
MAX_RANGES = 1000


def _pct(text: str, what: str, spec: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--ranges {spec!r}: {what} {text!r} is not a number (percent)") from None
    if not math.isfinite(value) or value < 0:
        raise InputError(f"--ranges {spec!r}: {what} {text!r} must be a finite percentage >= 0")
    return value


def parse_ranges(spec: str) -> tuple[DeviationRange, ...]:
    """Deviation ranges in percent: ``START:STOP:STEP`` (``0:50:10`` → 0–10, …, 40–50 %), ``LO:HI`` (one range)
    or a comma list ``LO-HI,LO-HI`` (``10-20,40-50``)."""
    text = spec.strip()
    if not text:
        raise InputError("--ranges is empty (expected START:STOP:STEP in percent, e.g. 0:50:10)")
    ranges: list[DeviationRange] = []
    if ":" in text:
        parts = text.split(":")
        if len(parts) not in (2, 3):
            raise InputError(f"--ranges {spec!r}: expected START:STOP:STEP or LO:HI (percent)")
        start = _pct(parts[0], "START", spec)
        stop = _pct(parts[1], "STOP", spec)
        step = _pct(parts[2], "STEP", spec) if len(parts) == 3 else stop - start
        if stop <= start:
            raise InputError(f"--ranges {spec!r}: STOP ({stop:g}) must be above START ({start:g})")
        if step <= 0:
            raise InputError(f"--ranges {spec!r}: STEP must be positive, got {step:g}")
        n = (stop - start) / step
        if n > MAX_RANGES:
            raise InputError(f"--ranges {spec!r}: {n:.3g} ranges; at most {MAX_RANGES} (use a larger STEP)")
        if abs(n - round(n)) > 1e-9:
            raise InputError(f"--ranges {spec!r}: STEP {step:g} does not divide STOP-START = {stop - start:g}")
        for k in range(round(n)):
            ranges.append(DeviationRange(round(start + k * step, 6) / 100, round(start + (k + 1) * step, 6) / 100))
    else:
        for item in text.split(","):
            bounds = item.strip().split("-")
            if len(bounds) != 2:
                raise InputError(f"--ranges {spec!r}: item {item.strip()!r} is not LO-HI (percent)")
            lo, hi = _pct(bounds[0], "LO", spec), _pct(bounds[1], "HI", spec)
            if hi <= lo:
                raise InputError(f"--ranges {spec!r}: item {item.strip()!r} needs HI > LO")
            ranges.append(DeviationRange(lo / 100, hi / 100))
    keys = [r.key for r in ranges]
    if len(set(keys)) != len(keys):
        raise InputError(f"--ranges {spec!r}: a range is listed twice")
    return tuple(ranges)


def draw_deviations(seed: int, rng_range: DeviationRange, run_indices: np.ndarray, n_params: int,
                    sign: str = "both") -> np.ndarray:
    """Relative deviations ``s*u`` of shape (runs, n_params) for the given run indices (see module doc)."""
    if sign not in SIGN_CONVENTIONS:
        raise InputError(f"sign convention must be one of {', '.join(SIGN_CONVENTIONS)}, got {sign!r}")
    lo_bp, hi_bp = rng_range.key
    out = np.empty((len(run_indices), n_params))
    for row, i in enumerate(run_indices):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(lo_bp, hi_bp, int(i))))
        mag = rng.uniform(rng_range.lo, rng_range.hi, n_params)
        flip = rng.random(n_params) < 0.5  # drawn in every convention so magnitudes do not depend on it
        signs = np.where(flip, -1.0, 1.0) if sign == "both" else np.full(n_params, -1.0 if sign == "minus" else 1.0)
        out[row] = signs * mag
    return out


def noise_generator(seed: int, rng_range: DeviationRange, run_index: int, mbit_key: str) -> np.random.Generator:
    """The measurement-noise generator of one run and MBIT (independent of the deviation draws)."""
    lo_bp, hi_bp = rng_range.key
    tag = zlib.crc32(mbit_key.encode())
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(lo_bp, hi_bp, int(run_index), 1, tag)))


@dataclass(frozen=True)
class CampaignSpec:
    """Everything that fixes a campaign's numbers (picklable: it travels to process and Dask workers)."""

    params_toml: str  # the nominal parameter set, serialised (workers rebuild the model from it)
    params_name: str
    mbits: tuple[MbitDefinition, ...]
    ranges: tuple[DeviationRange, ...]
    n_runs: int  # per range
    seed: int
    monitor: MonitorSettings
    deviated: tuple[str, ...] = DEFAULT_DEVIATED
    nominal_values: tuple[float, ...] = ()  # nominal values of ``deviated`` (SI), filled by make_spec
    sign: str = "both"
    noise_std: float = 0.0  # m, white measurement noise added to the hardware's z3 (0: none, as the paper)
    batch_size: int = DEFAULT_BATCH_SIZE
    rtol: float = 1e-6

    def __post_init__(self) -> None:
        if not isinstance(self.n_runs, int) or isinstance(self.n_runs, bool) or self.n_runs <= 0:
            raise InputError(f"--n must be a positive integer (runs per range), got {self.n_runs!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise InputError(f"--seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.batch_size, int) or self.batch_size <= 0:
            raise InputError(f"batch size must be a positive integer, got {self.batch_size!r}")
        if not self.mbits:
            raise InputError("a campaign needs at least one MBIT")
        if not self.ranges:
            raise InputError("a campaign needs at least one deviation range")
        if self.sign not in SIGN_CONVENTIONS:
            raise InputError(f"--sign must be one of {', '.join(SIGN_CONVENTIONS)}, got {self.sign!r}")
        if not (math.isfinite(self.noise_std) and self.noise_std >= 0):
            raise InputError(f"noise standard deviation must be >= 0 m, got {self.noise_std!r}")
        if not self.rtol > 0:
            raise InputError(f"rtol must be positive, got {self.rtol!r}")
        if len({m.key for m in self.mbits}) != len(self.mbits):
            raise InputError("an MBIT is listed twice")

    @property
    def mbit_keys(self) -> tuple[str, ...]:
        return tuple(m.key for m in self.mbits)

    def batches(self) -> list[BatchSpec]:
        """The campaign's batches in canonical order (range by range, runs in order)."""
        out = []
        for r_idx in range(len(self.ranges)):
            for start in range(0, self.n_runs, self.batch_size):
                out.append(BatchSpec(self, r_idx, start, min(start + self.batch_size, self.n_runs)))
        return out

    def describe(self) -> dict[str, Any]:  # the "spec" of manifest.json and campaign.json (JSON at the edge)
        """JSON-able description (unit-suffixed keys); :meth:`fingerprint` hashes it."""
        return {
            "store_version": STORE_VERSION,
            "params": self.params_name,
            "params_sha256": hashlib.sha256(self.params_toml.encode()).hexdigest(),
            "mbits": [m.describe() for m in self.mbits],
            "ranges_pct": [[r.lo * 100, r.hi * 100] for r in self.ranges],
            "n_runs_per_range": self.n_runs,
            "seed": self.seed,
            "deviated": list(self.deviated),
            "nominal_values_SI": list(self.nominal_values),
            "sign_convention": self.sign,
            "noise_std_m": self.noise_std,
            "batch_size": self.batch_size,
            "rtol": self.rtol,
            "monitor": {"f_mon_Hz": self.monitor.f_mon, "eps_th": self.monitor.eps_th,
                        "count_max": self.monitor.count_max, "counter_up": self.monitor.counter_up,
                        "counter_down": self.monitor.counter_down, "e0z_m": self.monitor.e0z,
                        "kerr_z": self.monitor.kerr_z},
        }

    def fingerprint(self) -> str:
        """Hash of everything that fixes the stored batch results."""
        return hashlib.sha256(json.dumps(self.describe(), sort_keys=True).encode()).hexdigest()[:20]


@dataclass(frozen=True)
class BatchSpec:
    """One task: runs ``[run_start, run_stop)`` of range ``range_index``, for every MBIT of the campaign."""

    campaign: CampaignSpec
    range_index: int
    run_start: int
    run_stop: int

    @property
    def range(self) -> DeviationRange:
        return self.campaign.ranges[self.range_index]

    @property
    def n(self) -> int:
        return self.run_stop - self.run_start

    @property
    def key(self) -> str:
        lo, hi = self.range.key
        return f"r{lo:05d}-{hi:05d}_i{self.run_start:05d}-{self.run_stop:05d}"


def check_deviation_bounds(names: tuple[str, ...], nominal: tuple[float, ...],
                           bounds: dict[str, tuple[float, float]], ranges: tuple[DeviationRange, ...],
                           sign: str) -> None:
    """Refuse ranges that would push a deviated parameter outside its physical bounds."""
    top = max(r.hi for r in ranges)
    factors = []
    if sign in ("both", "minus"):
        factors.append(1.0 - top)
    if sign in ("both", "plus"):
        factors.append(1.0 + top)
    for name, nom in zip(names, nominal):
        lo, hi = bounds.get(name, (-math.inf, math.inf))
        for f in factors:
            v = nom * f
            if not (lo <= v <= hi) or (f <= 0 and lo >= 0):
                raise InputError(f"--ranges up to {top * 100:g}% (sign {sign}) would put {name} at {v:g} "
                                 f"(nominal {nom:g}), outside its allowed range [{lo:g}, {hi:g}]")


def core_bounds() -> dict[str, tuple[float, float]]:
    """Physical bounds of the Table 2 parameters (from the board_config schema)."""
    return {name: (par.lower, par.upper) for name, par in CORE_SCHEMA.items()}
