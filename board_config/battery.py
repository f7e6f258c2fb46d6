"""Rechargeable cells for the harvesting model: ratings and open-circuit-voltage tables, validated on load.

``load_battery("ML2032")`` reads ``batteries.toml`` (ratings as quantity tables, SI units) and the cell's CSV table of
open-circuit voltage against discharged capacity (``data/ml2032_ocv.csv``; its header states its provenance). The
table gives the Thevenin model of the seed paper's Eq. 6::

    C_b(v_b) = -dq_d/dv_b     (F)

with ``q_d`` the discharged capacity (C = A*s; 0 when full, ``capacity`` at the cut-off voltage). The curve between
the table's points is a monotone cubic (PCHIP, :class:`MonotoneCubic`) of ``v_b(q_d)``, so ``C_b`` is finite and
positive everywhere.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, cast

import numpy as np

from board_config.errors import ConfigError, InputError
from board_config.quantities import QuantitySpec, parse_quantities, read_toml

CONFIG_DIR = Path(__file__).resolve().parent
BATTERIES_FILE = CONFIG_DIR / "batteries.toml"
MAH = 3.6  # coulombs per mAh

_POS: dict[str, Any] = {"lower": 0.0, "lower_open": True}
_RATINGS_SCHEMA: Mapping[str, QuantitySpec] = MappingProxyType({
    "nominal_voltage": QuantitySpec("V", **_POS),
    "capacity": QuantitySpec("C", **_POS),
    "cutoff_voltage": QuantitySpec("V", **_POS),
    "full_voltage": QuantitySpec("V", **_POS),
    "charge_voltage_max": QuantitySpec("V", **_POS),
})
_Q_COLUMN = "discharged_capacity_mAh"
_V_COLUMN = "open_circuit_voltage_V"
#: relative tolerance between the rating table and the CSV's end points (capacity, cut-off and full voltage)
_END_TOLERANCE = 5e-3


class MonotoneCubic:
    """Monotone piecewise-cubic Hermite interpolant (PCHIP, Fritsch-Butland slopes as in scipy), numpy only.

    Kept here (rather than scipy's) so that loading a cell does not import scipy; the compiled harvesting terminals
    use the same slope rule (``plant.effects.harvesting``). Values outside ``[x[0], x[-1]]`` use the end cubic.
    """

    def __init__(self, x: np.ndarray, y: np.ndarray) -> None:
        self.x = np.asarray(x, dtype=float)
        self.y = np.asarray(y, dtype=float)
        h = np.diff(self.x)
        m = np.diff(self.y) / h
        d = np.zeros_like(self.x)
        for k in range(1, self.x.size - 1):
            if m[k - 1] * m[k] > 0:
                w1, w2 = 2 * h[k] + h[k - 1], h[k] + 2 * h[k - 1]
                d[k] = (w1 + w2) / (w1 / m[k - 1] + w2 / m[k])
        d[0] = self._edge(h[0], h[1], m[0], m[1])
        d[-1] = self._edge(h[-1], h[-2], m[-1], m[-2])
        self.h, self.d = h, d

    @staticmethod
    def _edge(h0: float, h1: float, m0: float, m1: float) -> float:
        d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
        if d * m0 <= 0:
            return 0.0
        if m0 * m1 <= 0 and abs(d) > 3 * abs(m0):
            return 3.0 * m0
        return float(d)

    def __call__(self, xq: float | np.ndarray, order: int = 0) -> np.ndarray:
        """Value (order 0) or derivative (order 1, 2) at ``xq``."""
        xq = np.asarray(xq, dtype=float)
        k = np.clip(np.searchsorted(self.x, xq, side="right") - 1, 0, self.x.size - 2)
        h = self.h[k]
        s = (xq - self.x[k]) / h
        y0, y1 = self.y[k], self.y[k + 1]
        m0, m1 = self.d[k] * h, self.d[k + 1] * h
        value: np.ndarray  # (numpy's stubs type this arithmetic as Any)
        if order == 0:
            value = ((2 * s**3 - 3 * s**2 + 1) * y0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * y1
                     + (s**3 - s**2) * m1)
            return value
        if order == 1:
            value = ((6 * s**2 - 6 * s) * y0 + (3 * s**2 - 4 * s + 1) * m0 + (-6 * s**2 + 6 * s) * y1
                     + (3 * s**2 - 2 * s) * m1) / h
            return value
        if order == 2:
            value = ((12 * s - 6) * y0 + (6 * s - 4) * m0 + (-12 * s + 6) * y1 + (6 * s - 2) * m1) / h**2
            return value
        raise ValueError(f"order must be 0, 1 or 2, got {order!r}")

    def integral(self, a: float, b: float) -> float:
        """Integral from ``a`` to ``b`` (exact: Simpson's rule on each cubic piece)."""
        lo, hi, sign = (a, b, 1.0) if a <= b else (b, a, -1.0)
        cuts = np.unique(np.concatenate([[lo], self.x[(self.x > lo) & (self.x < hi)], [hi]]))
        l, r = cuts[:-1], cuts[1:]
        total = np.sum((r - l) / 6.0 * (self(l) + 4.0 * self(0.5 * (l + r)) + self(r)))
        return sign * float(total)


@dataclass(frozen=True)
class BatterySpec:
    """A rechargeable cell: ratings (SI) and its open-circuit-voltage curve ``v_oc(q_d)``.

    ``q_d`` (C) and ``v_oc`` (V) are the table's points (``q_d`` increasing from 0 = full to ``capacity`` = cut-off).
    """

    name: str
    description: str
    capacity: float  # C
    nominal_voltage: float  # V
    cutoff_voltage: float  # V
    full_voltage: float  # V
    charge_voltage_max: float  # V
    q_d: np.ndarray  # C
    v_oc: np.ndarray  # V
    table_file: str
    provenance: str
    _v_of_q: MonotoneCubic = field(init=False, repr=False, compare=False)  # the curve v_oc(q_d) between the points

    def __post_init__(self) -> None:
        object.__setattr__(self, "_v_of_q", MonotoneCubic(self.q_d, self.v_oc))

    def _dv_dq(self, q: float | np.ndarray) -> np.ndarray:
        """``dv_oc/dq_d`` (V/C) of the curve at ``q`` (C)."""
        return self._v_of_q(q, 1)

    def _d2v_dq2(self, q: float | np.ndarray) -> np.ndarray:
        """``d^2 v_oc/dq_d^2`` (V/C^2) of the curve at ``q`` (C)."""
        return self._v_of_q(q, 2)

    # --- range checks --------------------------------------------------------------------------------
    @property
    def voltage_range(self) -> tuple[float, float]:
        """(cut-off, full) open-circuit voltage of the table (V)."""
        return float(self.v_oc[-1]), float(self.v_oc[0])

    def check_voltage(self, v: float, what: str = "battery voltage") -> float:
        """``v`` (V) if it lies on the table, else a ValueError naming the value and the allowed range."""
        lo, hi = self.voltage_range
        v = float(v)
        if not np.isfinite(v) or v < lo - 1e-12 or v > hi + 1e-12:
            raise InputError(f"{what} {v!r} V is outside the {self.name} open-circuit-voltage table "
                             f"[{lo:g}, {hi:g}] V ({self.table_file})")
        return min(max(v, lo), hi)

    def check_discharged(self, q_d: float, what: str = "discharged capacity") -> float:
        q_d = float(q_d)
        if not np.isfinite(q_d) or q_d < 0.0 or q_d > self.capacity * (1 + 1e-12):
            raise InputError(f"{what} {q_d!r} C is outside [0, {self.capacity:g}] C (0 = full, "
                             f"{self.capacity:g} C = cut-off) for {self.name}")
        return min(q_d, self.capacity)

    # --- the curve ------------------------------------------------------------------------------------
    def ocv(self, q_d: float | np.ndarray) -> np.ndarray:
        """Open-circuit voltage (V) at discharged capacity ``q_d`` (C); extrapolated linearly outside the table."""
        q = np.asarray(q_d, dtype=float)
        inside = np.clip(q, 0.0, self.capacity)
        v = np.asarray(self._v_of_q(inside))
        slope_full = float(self._dv_dq(0.0))
        slope_cut = float(self._dv_dq(self.capacity))
        v = np.where(q < 0.0, self.v_oc[0] + slope_full * q, v)
        return np.where(q > self.capacity, self.v_oc[-1] + slope_cut * (q - self.capacity), v)

    def discharged_capacity(self, v: float | np.ndarray) -> np.ndarray:
        """Inverse of :meth:`ocv` on the table: ``q_d`` (C) with ``ocv(q_d) = v``; ``v`` must lie on the table."""
        v_arr = np.atleast_1d(np.asarray(v, dtype=float))
        for value in v_arr.ravel():
            self.check_voltage(value, "open-circuit voltage")
        lo = np.zeros_like(v_arr)
        hi = np.full_like(v_arr, self.capacity)
        for _ in range(60):  # bisection on a strictly decreasing curve: 2^-60 of the capacity
            mid = 0.5 * (lo + hi)
            above = self.ocv(mid) > v_arr
            lo = np.where(above, mid, lo)
            hi = np.where(above, hi, mid)
        q = 0.5 * (lo + hi)
        return cast(np.ndarray, q if np.ndim(v) else q.reshape(()))

    def capacitance(self, v: float | np.ndarray) -> np.ndarray:
        """Eq. 6: the equivalent capacitance ``C_b = -dq_d/dv_b`` (F) at open-circuit voltage ``v`` (V)."""
        q = self.discharged_capacity(v)
        return -1.0 / np.asarray(self._dv_dq(q))

    def d2qd_dv2(self, v: float | np.ndarray) -> np.ndarray:
        """``d^2 q_d / dv_b^2`` (C/V^2) at ``v`` (V), the extra term of the paper's Eq. 9-10."""
        q = self.discharged_capacity(v)
        d1 = np.asarray(self._dv_dq(q))
        d2 = np.asarray(self._d2v_dq2(q))
        return cast(np.ndarray, -d2 / d1**3)

    def stored_energy(self, q_d: float | np.ndarray) -> np.ndarray:
        """Chemical energy (J) the cell can still deliver down to the cut-off: ``integral of v_oc dq`` from
        ``q_d`` to ``capacity``."""
        q = np.clip(np.asarray(q_d, dtype=float), 0.0, self.capacity)
        integ = self._v_of_q.integral
        return cast(np.ndarray, np.vectorize(lambda qq: integ(float(qq), self.capacity))(q))

    def state_of_charge(self, q_d: float | np.ndarray) -> np.ndarray:
        """1 when full, 0 at the cut-off (may leave [0, 1] when a model overshoots the table)."""
        return 1.0 - np.asarray(q_d, dtype=float) / self.capacity

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name, "description": self.description, "capacity_C": self.capacity,
            "capacity_mAh": self.capacity / MAH, "nominal_voltage_V": self.nominal_voltage,
            "cutoff_voltage_V": self.cutoff_voltage, "full_voltage_V": self.full_voltage,
            "charge_voltage_max_V": self.charge_voltage_max, "table": self.table_file,
            "full_charge_energy_J": float(self.stored_energy(0.0)),
        }


def available_batteries(path: str | Path | None = None) -> list[str]:
    """Names of the cells described in ``batteries.toml``."""
    data = read_toml(Path(path) if path is not None else BATTERIES_FILE)
    return sorted(data)


def load_battery(name: str = "ML2032", path: str | Path | None = None) -> BatterySpec:
    """Load and check a cell by name; errors name the file, key/row/column and the reason."""
    toml_path = Path(path) if path is not None else BATTERIES_FILE
    file = str(toml_path)
    data = read_toml(toml_path)
    if name not in data:
        raise ConfigError(file, str(name), f"unknown battery (known: {', '.join(sorted(data)) or 'none'})")
    entry = data[name]
    if not isinstance(entry, Mapping):
        raise ConfigError(file, name, "expected a table")
    extra = set(entry) - {"description", "ocv_table", "ratings"}
    if extra:
        raise ConfigError(file, f"{name}.{sorted(extra)[0]}", "unknown key (expected description, ocv_table, ratings)")
    table_rel = entry.get("ocv_table")
    if not isinstance(table_rel, str) or not table_rel:
        raise ConfigError(file, f"{name}.ocv_table", "missing: the path of the open-circuit-voltage CSV")
    ratings, _ = parse_quantities(file, f"{name}.ratings", entry.get("ratings"), _RATINGS_SCHEMA)
    table_path = (toml_path.parent / table_rel).resolve()
    q_mah, v, provenance = read_ocv_table(table_path)
    q = q_mah * MAH
    where = str(table_path)
    checks = (
        ("capacity", ratings["capacity"], q[-1], f"last row {_Q_COLUMN} ({q_mah[-1]:g} mAh = {q[-1]:g} C)"),
        ("cutoff_voltage", ratings["cutoff_voltage"], v[-1], f"last row {_V_COLUMN} ({v[-1]:g} V)"),
        ("full_voltage", ratings["full_voltage"], v[0], f"first row {_V_COLUMN} ({v[0]:g} V)"),
    )
    for key, rated, tabled, label in checks:
        if abs(rated - tabled) > _END_TOLERANCE * abs(rated):
            raise ConfigError(file, f"{name}.ratings.{key}", f"rated {rated:g} disagrees with {where} {label}")
    if not ratings["cutoff_voltage"] < ratings["full_voltage"] <= ratings["charge_voltage_max"]:
        raise ConfigError(file, f"{name}.ratings", "need cutoff_voltage < full_voltage <= charge_voltage_max")
    spec = BatterySpec(
        name=name, description=str(entry.get("description", name)), capacity=float(q[-1]),
        nominal_voltage=float(ratings["nominal_voltage"]), cutoff_voltage=float(v[-1]),
        full_voltage=float(v[0]), charge_voltage_max=float(ratings["charge_voltage_max"]),
        q_d=q, v_oc=v, table_file=where, provenance=provenance,
    )
    slopes = np.asarray(spec._dv_dq(q))
    if not np.all(slopes < 0):
        bad = int(np.argmax(slopes >= 0))
        raise ConfigError(where, f"row {bad + 1}", "the interpolated curve is flat there: C_b = -dq_d/dv_b would be "
                          "infinite (make the voltage strictly decreasing with a non-zero slope)")
    return spec


def read_ocv_table(path: str | Path) -> tuple[np.ndarray, np.ndarray, str]:
    """Read an OCV CSV: ``#`` provenance header, then columns ``discharged_capacity_mAh,open_circuit_voltage_V``.

    Returns (q_d in mAh, v_oc in V, provenance text). Rows are numbered as data rows (1 = first after the header).
    """
    path = Path(path)
    file = str(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(file, "-", "open-circuit-voltage table not found") from None
    except OSError as exc:
        raise ConfigError(file, "-", f"cannot read: {exc}") from None
    comment = [ln[1:].strip() for ln in text.splitlines() if ln.startswith("#")]
    rows = [row for row in csv.reader(ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#"))]
    if not comment:
        raise ConfigError(file, "header", "missing provenance header ('#' lines saying where the curve comes from)")
    if not rows:
        raise ConfigError(file, "-", "no data")
    header = [h.strip() for h in rows[0]]
    if header != [_Q_COLUMN, _V_COLUMN]:
        raise ConfigError(file, "header", f"columns must be '{_Q_COLUMN},{_V_COLUMN}', got '{','.join(header)}'")
    q_list: list[float] = []
    v_list: list[float] = []
    for i, row in enumerate(rows[1:], start=1):
        if len(row) != 2:
            raise ConfigError(file, f"row {i}", f"expected 2 columns, got {len(row)}: {row!r}")
        for col, cell, out in ((_Q_COLUMN, row[0], q_list), (_V_COLUMN, row[1], v_list)):
            try:
                value = float(cell)
            except ValueError:
                raise ConfigError(file, f"row {i}, column {col}", f"not a number: {cell!r}") from None
            if not np.isfinite(value):
                raise ConfigError(file, f"row {i}, column {col}", f"value must be finite, got {cell!r}")
            out.append(value)
    if len(q_list) < 3:
        raise ConfigError(file, "-", f"need at least 3 rows, got {len(q_list)}")
    q = np.array(q_list)
    v = np.array(v_list)
    if q[0] != 0.0:
        raise ConfigError(file, f"row 1, column {_Q_COLUMN}", f"must start at 0 (full cell), got {q[0]:g}")
    for i in range(1, q.size):
        if not q[i] > q[i - 1]:
            raise ConfigError(file, f"row {i + 1}, column {_Q_COLUMN}",
                              f"must increase strictly ({q[i]:g} after {q[i - 1]:g})")
        if not v[i] < v[i - 1]:
            raise ConfigError(file, f"row {i + 1}, column {_V_COLUMN}",
                              f"must decrease strictly ({v[i]:g} after {v[i - 1]:g}): C_b = -dq_d/dv_b > 0")
    if v[-1] <= 0:
        raise ConfigError(file, f"row {q.size}, column {_V_COLUMN}", f"voltage must stay positive, got {v[-1]:g}")
    return q, v, "\n".join(comment)
