"""A finished campaign's runs in memory: per-run draws and verdicts, error traces, summaries, files.

Files written by :meth:`CampaignResult.save` (all in the output directory):

* ``fig11_table.csv`` / ``fig11_table.md`` — detected faults and probability per MBIT and range, 95 % Wilson
  interval (``mbit = any`` counts a unit as caught if either MBIT caught it);
* ``paper_comparison.csv`` — the paper's stated probabilities against ours on the paper's ranges;
* ``runs.csv`` — one row per unit: range, deviations (%), parameter values (SI), per MBIT verdict, fault time,
  peak error and peak counter, integration status;
* ``traces.npz`` — the normalised-error traces ``eps_<m>`` (runs × samples) and measured ``z3_meas_<m>_m`` with
  ``t_<m>_s``, ``z3_model_<m>_m``, ``range_lo``/``range_hi`` (fractions), ``status_<m>`` — what the ROC view
  sweeps without re-simulating.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from board_config import MonitorSettings
from board_config.errors import InputError
from studies.campaign.paper import PAPER_FAULT_PROBABILITY
from studies.campaign.spec import CampaignSpec
from studies.campaign.statistics import DetectionStat, wilson_interval

_TOL = 1e-9


@dataclass
class MbitRuns:
    """All units' results for one MBIT."""

    key: str
    label: str
    t: np.ndarray  # (T,) s
    z3_model: np.ndarray  # (T,) m, nominal prediction
    z3_meas: np.ndarray  # (N, T) m, degraded "hardware"
    eps: np.ndarray  # (N, T) normalised error (1)
    fault: np.ndarray  # (N,) bool
    fault_time: np.ndarray  # (N,) s, NaN if none
    max_count: np.ndarray  # (N,)
    max_eps: np.ndarray  # (N,)
    status: np.ndarray  # (N,) integration status, 0 = ok


@dataclass
class CampaignResult:
    """The assembled campaign (runs ordered range by range, then by run index)."""

    spec: CampaignSpec
    range_index: np.ndarray  # (N,)
    run_index: np.ndarray  # (N,)
    rel_dev: np.ndarray  # (N, P) relative deviations (fractions, signed)
    values: np.ndarray  # (N, P) parameter values (SI)
    mbits: dict[str, MbitRuns]
    param_units: tuple[str, ...] = ()

    @classmethod
    def from_batches(cls, spec: CampaignSpec, batches: list[dict[str, np.ndarray]],
                     param_units: tuple[str, ...] = ()) -> CampaignResult:
        def cat(name: str) -> np.ndarray:
            return np.concatenate([b[name] for b in batches], axis=0)

        mbits = {}
        for defn in spec.mbits:
            p = f"mbit_{defn.key}_"
            first = batches[0]
            mbits[defn.key] = MbitRuns(
                key=defn.key, label=defn.label, t=first[p + "t_s"], z3_model=first[p + "z3_model_m"],
                z3_meas=cat(p + "z3_meas_m"), eps=cat(p + "eps"), fault=cat(p + "fault").astype(bool),
                fault_time=cat(p + "fault_time_s"), max_count=cat(p + "max_count"), max_eps=cat(p + "max_eps"),
                status=cat(p + "status"))
        return cls(spec, cat("range_index"), cat("run_index"), cat("rel_dev"), cat("values"), mbits,
                   tuple(param_units))

    # --- statistics ---------------------------------------------------------------------------------
    @property
    def range_lo(self) -> np.ndarray:
        return np.array([self.spec.ranges[i].lo for i in self.range_index])

    @property
    def range_hi(self) -> np.ndarray:
        return np.array([self.spec.ranges[i].hi for i in self.range_index])

    def _stat(self, key: str, mask: np.ndarray, lo: float, hi: float) -> DetectionStat:
        if key == "any":
            ok = np.all([r.status == 0 for r in self.mbits.values()], axis=0)
            det = np.any([r.fault for r in self.mbits.values()], axis=0)
            label = " or ".join(r.label for r in self.mbits.values())
        else:
            runs = self.mbits[key]
            ok, det, label = runs.status == 0, runs.fault, runs.label
        return DetectionStat(key, label, lo, hi, int(mask.sum()), int((mask & ~ok).sum()),
                             int((mask & ok & det).sum()))

    def summary(self) -> list[DetectionStat]:
        """Per MBIT (and ``any`` when there are several) and per range."""
        keys = [*self.mbits, *(["any"] if len(self.mbits) > 1 else [])]
        return [self._stat(k, self.range_index == i, r.lo, r.hi)
                for k in keys for i, r in enumerate(self.spec.ranges)]

    def pooled(self, key: str, lo: float, hi: float) -> DetectionStat | None:
        """Pool the ranges inside ``[lo, hi]``; ``None`` unless they cover it exactly."""
        inside = [i for i, r in enumerate(self.spec.ranges) if r.lo >= lo - _TOL and r.hi <= hi + _TOL]
        covered = sorted((self.spec.ranges[i].lo, self.spec.ranges[i].hi) for i in inside)
        edge = lo
        for a, b in covered:
            if a > edge + _TOL:
                return None
            edge = max(edge, b)
        if not covered or edge < hi - _TOL:
            return None
        return self._stat(key, np.isin(self.range_index, inside), lo, hi)

    def paper_comparison(self) -> list[dict[str, Any]]:
        """The paper's stated probabilities against ours (pooled on the paper's ranges): the rows of
        paper_comparison.csv (column name → cell, the file at the edge)."""
        rows = []
        for key, claims in PAPER_FAULT_PROBABILITY.items():
            if key not in self.mbits:
                continue
            for lo, hi, p_paper in claims:
                st = self.pooled(key, lo, hi)
                row: dict[str, Any] = {"mbit": key, "label": self.mbits[key].label, "range_lo_pct": lo * 100,
                                       "range_hi_pct": hi * 100, "paper_probability": p_paper}
                if st is None:
                    row.update({"n_runs": 0, "n_detected": 0, "probability": math.nan, "ci95_low": math.nan,
                                "ci95_high": math.nan, "paper_inside_ci95": None})
                else:
                    c_lo, c_hi = st.interval
                    row.update({"n_runs": st.n_valid, "n_detected": st.n_detected, "probability": st.probability,
                                "ci95_low": c_lo, "ci95_high": c_hi,
                                "paper_inside_ci95": bool(c_lo - _TOL <= p_paper <= c_hi + _TOL)})
                rows.append(row)
        return rows

    @property
    def n_failed(self) -> int:
        return int(sum(int((r.status != 0).sum()) for r in self.mbits.values()))

    # --- files --------------------------------------------------------------------------------------
    def save(self, out: Path) -> dict[str, Path]:
        """Write the table, per-run CSV, paper comparison and traces (see the module doc)."""
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"table_csv": out / "fig11_table.csv", "table_md": out / "fig11_table.md",
                 "runs_csv": out / "runs.csv", "paper_csv": out / "paper_comparison.csv",
                 "traces": out / "traces.npz"}
        rows = [s.row() for s in self.summary()]
        write_rows(paths["table_csv"], rows)
        paths["table_md"].write_text(self.markdown_table() + "\n")
        write_rows(paths["paper_csv"], self.paper_comparison())
        write_rows(paths["runs_csv"], self.run_rows())
        arrays: dict[str, np.ndarray] = {
            "range_lo": self.range_lo, "range_hi": self.range_hi, "run_index": self.run_index,
            "rel_dev": self.rel_dev, "values": self.values, "deviated": np.array(self.spec.deviated),
            "mbit_keys": np.array(list(self.mbits)), "mbit_labels": np.array([r.label for r in self.mbits.values()]),
            "monitor": np.array([self.spec.monitor.f_mon, self.spec.monitor.eps_th, self.spec.monitor.count_max,
                                 self.spec.monitor.counter_up, self.spec.monitor.counter_down,
                                 self.spec.monitor.e0z, self.spec.monitor.kerr_z]),
        }
        for key, r in self.mbits.items():
            arrays.update({f"t_{key}_s": r.t, f"z3_model_{key}_m": r.z3_model, f"z3_meas_{key}_m": r.z3_meas,
                           f"eps_{key}": r.eps, f"status_{key}": r.status, f"fault_{key}": r.fault})
        tmp = paths["traces"].with_name(".traces.npz.tmp")
        with tmp.open("wb") as fh:
            np.savez(fh, allow_pickle=False, **arrays)  # plain arrays: loaded with allow_pickle=False too
        tmp.replace(paths["traces"])
        return paths

    def run_rows(self) -> list[dict[str, Any]]:
        """The rows of runs.csv (column name → cell, the file at the edge)."""
        rows = []
        units = self.param_units or ("SI",) * len(self.spec.deviated)
        for n in range(self.run_index.size):
            r = self.spec.ranges[int(self.range_index[n])]
            row: dict[str, Any] = {"range_lo_pct": r.lo * 100, "range_hi_pct": r.hi * 100,
                                   "run_index": int(self.run_index[n])}
            for j, name in enumerate(self.spec.deviated):
                row[f"dev_{name}_pct"] = 100.0 * float(self.rel_dev[n, j])
            for j, name in enumerate(self.spec.deviated):
                row[f"{name}_{_unit_tag(units[j])}"] = float(self.values[n, j])
            for key, m in self.mbits.items():
                row[f"fault_{key}"] = int(m.fault[n])
                row[f"fault_time_{key}_s"] = float(m.fault_time[n])
                row[f"max_eps_{key}"] = float(m.max_eps[n])
                row[f"max_count_{key}"] = int(m.max_count[n])
                row[f"status_{key}"] = int(m.status[n])
            rows.append(row)
        return rows

    def markdown_table(self) -> str:
        paper = {(k, round(lo, 6), round(hi, 6)): p for k, cl in PAPER_FAULT_PROBABILITY.items()
                 for lo, hi, p in cl}
        lines = ["| MBIT | deviation range | runs | integration failures | detected | P(fault) | 95 % Wilson CI "
                 "| paper |", "| --- | --- | ---: | ---: | ---: | ---: | --- | --- |"]
        for s in self.summary():
            c_lo, c_hi = s.interval
            p_paper = paper.get((s.mbit, round(s.lo, 6), round(s.hi, 6)))
            lines.append(f"| {s.label} | {s.range_label} | {s.n_runs} | {s.n_failed} | {s.n_detected} | "
                         f"{_fmt_pct(s.probability)} | {_fmt_pct(c_lo)}–{_fmt_pct(c_hi)} | "
                         f"{'' if p_paper is None else _fmt_pct(p_paper)} |")
        return "\n".join(lines)


def _fmt_pct(p: float) -> str:
    return "n/a" if not math.isfinite(p) else f"{100 * p:.0f} %"


def _unit_tag(unit: str) -> str:
    return unit.replace("*", "").replace("/", "_per_").replace(" ", "")


def write_rows(path: Path, rows: list[dict[str, Any]]) -> None:
    """A CSV file of ``rows`` (column name → cell; the header from the first row), written atomically."""
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as fh:
        if rows:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            for row in rows:
                w.writerow({k: ("" if isinstance(v, float) and not math.isfinite(v) else
                                (f"{v:.10g}" if isinstance(v, float) else v)) for k, v in row.items()})
    tmp.replace(path)


@dataclass
class StoredTraces:
    """What the ROC view needs, read back from ``traces.npz``."""

    range_lo: np.ndarray
    range_hi: np.ndarray
    eps: dict[str, np.ndarray]
    status: dict[str, np.ndarray]
    fault: dict[str, np.ndarray]
    labels: dict[str, str]
    monitor: MonitorSettings


def load_traces(path: Path) -> StoredTraces:
    """Read ``traces.npz`` (a file or the campaign directory holding it)."""
    path = Path(path)
    if path.is_dir():
        path = path / "traces.npz"
    if not path.exists():
        raise InputError(f"{path}: no stored campaign traces (run `shm campaign ... --out DIR` first)")
    try:
        with np.load(path, allow_pickle=False) as z:
            keys = [str(k) for k in z["mbit_keys"]]
            labels = [str(k) for k in z["mbit_labels"]]
            mon = z["monitor"]
            return StoredTraces(
                range_lo=z["range_lo"], range_hi=z["range_hi"],
                eps={k: z[f"eps_{k}"] for k in keys}, status={k: z[f"status_{k}"] for k in keys},
                fault={k: z[f"fault_{k}"] for k in keys}, labels=dict(zip(keys, labels)),
                monitor=MonitorSettings(f_mon=float(mon[0]), eps_th=float(mon[1]), count_max=int(mon[2]),
                                        counter_up=int(mon[3]), counter_down=int(mon[4]), e0z=float(mon[5]),
                                        kerr_z=float(mon[6])))
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: not a readable campaign traces file ({exc})") from None


def save_json(path: Path, obj: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(obj, indent=2, default=_json_default, allow_nan=False))
    tmp.replace(path)


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


__all__ = ["CampaignResult", "MbitRuns", "StoredTraces", "load_traces", "save_json", "wilson_interval",
           "write_rows"]
