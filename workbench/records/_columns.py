"""Columns with units and metadata -> a validated time :class:`Record` (SI units), whatever file they came from."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from plant.layout import N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD
from workbench.records._metadata import check_meta
from workbench.records._types import (
    INPUT_QUANTITIES,
    KNOWN_QUANTITY_UNITS,
    Channel,
    Gap,
    Record,
    RecordError,
    Segment,
)
from workbench.records._units import Unit, known_units, split_column


def parse_columns(file: Path, names: Sequence[str], line: int | None) -> list[tuple[str, Unit]]:
    out: list[tuple[str, Unit]] = []
    seen: dict[str, str] = {}
    for col in names:
        if not col:
            raise RecordError(file, "empty column name", line=line)
        qty, unit = split_column(col)
        if unit is None:
            last = col.rsplit("_", 1)[-1] if "_" in col else ""
            reason = (f"unknown unit '{last}'" if last else "no unit suffix") + \
                f" (a column is named <quantity>_<unit>, e.g. z3_m; known units: {known_units()})"
            raise RecordError(file, reason, line=line, column=col)
        expected = KNOWN_QUANTITY_UNITS.get(qty)
        if expected is not None and unit.si != expected:
            raise RecordError(file, f"'{qty}' is measured in {expected}, but the unit '{unit.token}' is {unit.si}",
                              line=line, column=col)
        if qty in seen:
            raise RecordError(file, f"quantity '{qty}' appears twice (also as column '{seen[qty]}')",
                              line=line, column=col)
        seen[qty] = col
        out.append((qty, unit))
    return out


def _lost_cells(file: Path, data: np.ndarray, meta: dict[str, Any], lost: np.ndarray | None,
                colnames: list[str], locate: Callable[[int], str], timed: bool) -> np.ndarray:
    """The cells marked as lost samples (``lost``: the reader's empty cells; with ``missing = "nan"`` every NaN);
    any other non-finite value is an error, and so is a lost time."""
    mark = np.zeros(data.shape, bool) if lost is None else np.asarray(lost, bool)
    if meta.get("missing") == "nan":
        mark = mark | np.isnan(data)
    bad = ~np.isfinite(data) & ~mark
    if bad.any():
        k, j = np.argwhere(bad)[0]
        hint = ("" if "missing" in meta else "; if the logger lost this sample, say so in the metadata: "
                "missing = \"nan\" (docs/records.md, Lost samples)")
        raise RecordError(file, f"value {float(data[k, j])!r} is not finite (NaN/Inf are not allowed; cut the stretch "
                                f"out or split the record{hint})", where=locate(int(k)), column=colnames[j])
    if timed and mark[:, 0].any():
        k = int(np.flatnonzero(mark[:, 0])[0])
        raise RecordError(file, "the time of a row is missing (a lost sample keeps its time; only measured values "
                                "may be empty)", where=locate(k), column=colnames[0])
    return mark


def _gaps(t: np.ndarray, rows_lost: np.ndarray) -> tuple[Gap, ...]:
    """Runs of lost rows as :class:`Gap` (times in s)."""
    idx = np.flatnonzero(rows_lost)
    if idx.size == 0:
        return ()
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [idx.size - 1]])
    return tuple(Gap(float(t[idx[a]]), float(t[idx[b]]), int(b - a + 1)) for a, b in zip(starts, ends))


def build_record(file: Path, columns: Sequence[str], data: np.ndarray, meta: dict[str, Any],
                 locate: Callable[[int], str], time_si: np.ndarray | None = None,
                 lost: np.ndarray | None = None) -> Record:
    """Validate and assemble. ``data[:, j]`` holds column ``columns[j]`` as written (not yet SI).

    ``locate(k)`` names sample ``k`` for messages (a file line for CSV, a sample index for TDMS). When
    ``time_si`` is given (TDMS waveform timing) there is no time column in ``columns``. ``lost`` marks the
    cells the reader found empty (lost samples; with ``missing = "nan"`` NaN cells are lost too): their rows are
    left out of the record and listed in :attr:`Record.gaps`.
    """
    check_meta(file, meta)
    header_line = None
    parsed = parse_columns(file, columns, header_line)
    colnames = list(columns)
    mark = _lost_cells(file, data, meta, lost, colnames, locate, time_si is None)
    rows_lost: np.ndarray = np.asarray(mark.any(axis=1), bool)
    t, first = _time_track(file, parsed, colnames, data, locate, time_si, rows_lost)
    _check_sample_rate(file, meta, t)
    by_col = {c: parsed[j] for j, c in enumerate(colnames)}
    data_cols = colnames[first:]
    chan_meta: dict[str, dict[str, Any]] = meta.get("channels", {})
    for col in chan_meta:
        if col not in by_col:
            raise RecordError(file, f"describes column '{col}', which the record does not have "
                                    f"(columns: {', '.join(colnames)})", key=f"channels.{col}")
    inputs_cols = _input_columns(file, meta, by_col, colnames, data_cols)
    outputs_cols = _output_columns(file, meta, by_col, colnames, data_cols, inputs_cols)
    channels: dict[str, Channel] = {}
    for j, col in enumerate(colnames):
        if col not in inputs_cols and col not in outputs_cols:
            continue
        qty, unit = by_col[col]
        spec = chan_meta.get(col, {})
        noise = spec.get("noise_std")
        channels[qty] = Channel(
            name=qty, column=col, unit=unit, values=np.ascontiguousarray(unit.to_si(data[:, j]), dtype=float),
            role="input" if col in inputs_cols else "output", model_output=spec.get("model_output"),
            sensor=spec.get("sensor"), position_m=spec.get("position_m"),
            noise_std=None if noise is None else float(noise) * unit.factor, description=spec.get("description", ""),
        )
    segments = tuple(Segment(float(s["start_s"]), float(s["end_s"]), s["label"]) for s in meta.get("segments", []))
    test = meta.get("test", "other")
    rec = Record(
        path=str(file), test=test, t=np.ascontiguousarray(t, dtype=float), channels=MappingProxyType(channels),
        inputs=tuple(by_col[c][0] for c in inputs_cols), outputs=tuple(by_col[c][0] for c in outputs_cols),
        segments=segments, terminal=meta.get("terminal"), meta=MappingProxyType(dict(meta)),
    )
    return _without_lost_rows(rec, rows_lost) if rows_lost.any() else rec


def _time_track(file: Path, parsed: list[tuple[str, Unit]], colnames: list[str], data: np.ndarray,
                locate: Callable[[int], str], time_si: np.ndarray | None, rows_lost: np.ndarray
                ) -> tuple[np.ndarray, int]:
    """The time of every row in s (the first column, or ``time_si``), checked: at least 2 samples kept and
    strictly increasing; with the index of the first data column."""
    if time_si is None:
        if not parsed or parsed[0][0] != "time":
            raise RecordError(file, f"the first column must be the time, e.g. 'time_s' (got '{colnames[0]}')",
                              column=colnames[0] if colnames else None)
        t = parsed[0][1].to_si(data[:, 0])
        first = 1
    else:
        t = np.asarray(time_si, dtype=float)
        first = 0
        if t.size != data.shape[0]:
            raise RecordError(file, f"time track has {t.size} samples but the channels have {data.shape[0]}")
    if t.size - int(np.count_nonzero(rows_lost)) < 2:
        raise RecordError(file, f"needs at least 2 samples, found {t.size - int(np.count_nonzero(rows_lost))}"
                          + (f" ({int(np.count_nonzero(rows_lost))} lost)" if rows_lost.any() else ""))
    d = np.diff(t)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0]) + 1
        raise RecordError(file, f"time is not strictly increasing ({t[k - 1]:.9g} s then {t[k]:.9g} s)",
                          where=locate(k), column=colnames[0] if time_si is None else "time")
    return t, first


def _check_sample_rate(file: Path, meta: dict[str, Any], t: np.ndarray) -> None:
    """A declared ``sample_rate_Hz`` must agree with the time column within 1 %."""
    if "sample_rate_Hz" in meta:
        fs = float(meta["sample_rate_Hz"])
        fs_t = 1.0 / float(np.median(np.diff(t)))
        if abs(fs_t - fs) > 0.01 * fs:
            raise RecordError(file, f"sample_rate_Hz = {fs:g} but the time column has {fs_t:.6g} Hz",
                              key="sample_rate_Hz")


def _input_columns(file: Path, meta: dict[str, Any], by_col: dict[str, tuple[str, Unit]], colnames: list[str],
                   data_cols: list[str]) -> list[str]:
    """The input columns: ``meta["inputs"]``, else every data column of a model input quantity; checked."""
    inputs_cols: list[str] | None = meta.get("inputs")
    if inputs_cols is None:
        inputs_cols = [c for c in data_cols if by_col[c][0] in INPUT_QUANTITIES]
    for c in inputs_cols:
        if c not in by_col or c not in data_cols:
            raise RecordError(file, f"input column '{c}' is missing (columns: {', '.join(colnames)})",
                              key="inputs", column=c)
        if by_col[c][0] not in INPUT_QUANTITIES:
            raise RecordError(file, f"'{by_col[c][0]}' is not a model input (inputs: "
                                    f"{', '.join(INPUT_QUANTITIES)})", key="inputs", column=c)
    in_q = {by_col[c][0] for c in inputs_cols}
    if "va" in in_q and in_q & {"v_ch1", "v_ch2"}:
        raise RecordError(file, "give either the differential drive 'va' or the channel voltages v_ch1/v_ch2, "
                                "not both", key="inputs")
    if not inputs_cols:
        raise RecordError(file, f"no input channel (expected one of {', '.join(INPUT_QUANTITIES)} with a unit, "
                                "e.g. v_ch1_V; or list them under 'inputs')", key="inputs")
    return inputs_cols


def _output_columns(file: Path, meta: dict[str, Any], by_col: dict[str, tuple[str, Unit]], colnames: list[str],
                    data_cols: list[str], inputs_cols: list[str]) -> list[str]:
    """The output columns: ``meta["outputs"]``, else every data column that is not an input; checked."""
    outputs_cols: list[str] | None = meta.get("outputs")
    if outputs_cols is None:
        outputs_cols = [c for c in data_cols if c not in inputs_cols]
    for c in outputs_cols:
        if c not in by_col or c not in data_cols:
            raise RecordError(file, f"output column '{c}' is missing (columns: {', '.join(colnames)})",
                              key="outputs", column=c)
        if c in inputs_cols:
            raise RecordError(file, "listed as both input and output", key="outputs", column=c)
    if not outputs_cols:
        raise RecordError(file, "no measured output channel (e.g. z3_m)", key="outputs")
    return outputs_cols


def _without_lost_rows(rec: Record, rows_lost: np.ndarray) -> Record:
    """``rec`` with its lost rows left out, their stretches in ``gaps`` and the full input track kept (an input
    cell lost itself is interpolated in the track from its neighbours)."""
    keep = ~rows_lost
    full_t = rec.t
    u_all = np.zeros((full_t.size, N_INPUTS))
    for name in rec.inputs:
        v = rec.channels[name].values
        ok = np.isfinite(v)
        rec_v = v if ok.all() else np.interp(full_t, full_t[ok], v[ok])
        if name == "va":
            u_all[:, U_V_CH1] += rec_v
            u_all[:, U_V_CH2] -= rec_v
        else:
            u_all[:, {"v_ch1": U_V_CH1, "v_ch2": U_V_CH2, "z0dd": U_Z0DD}[name]] += rec_v
    chans = {n: replace(c, values=np.ascontiguousarray(c.values[keep])) for n, c in rec.channels.items()}
    return replace(rec, t=np.ascontiguousarray(full_t[keep]), channels=MappingProxyType(chans),
                   gaps=_gaps(full_t, rows_lost), input_track=(full_t, u_all))
