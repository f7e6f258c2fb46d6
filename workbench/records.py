"""Measurement records: CSV (with a TOML header or sidecar), TDMS import (npTDMS), frequency-response tables.

The format is documented in ``docs/records.md``. In short, a time record is a CSV file::

    # format = "mfc-shm-record/1"
    # test = "mbit-a"
    # sample_rate_Hz = 1000.0
    # inputs = ["v_ch1_V", "v_ch2_V"]
    # [channels.z3_m]
    # sensor = "laser E1"
    # position_m = 0.38
    time_s,v_ch1_V,v_ch2_V,z3_m
    0,100,100,0
    ...

Leading ``#`` lines form a TOML document (the metadata); the first other line names the columns, each with
its unit as a suffix (:mod:`workbench.units`); the rest are numbers. Metadata may also sit in a sidecar
``<stem>.meta.toml`` beside the data file (CSV or TDMS). Values are converted to SI at load time.

Every problem is a :class:`RecordError` naming the file, the line (or sample) and column, and the reason.
"""

from __future__ import annotations

import io
import logging
import math
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from board_config.errors import InputError
from plant.layout import INPUT_NAMES, N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD
from plant.signals import InputSignals
from workbench.units import Unit, known_units, split_column, unit_from_string

FORMAT = "mfc-shm-record/1"
FRF_FORMAT = "mfc-shm-frf/1"

#: Model inputs a record may carry (``va`` is the differential drive, expanded to v_ch1 = +va, v_ch2 = -va).
INPUT_QUANTITIES: dict[str, str] = {"v_ch1": "V", "v_ch2": "V", "z0dd": "m/s^2", "va": "V"}
#: SI unit expected for the quantities the plant knows (others may carry any known unit).
KNOWN_QUANTITY_UNITS: dict[str, str] = {
    "time": "s", **INPUT_QUANTITIES,
    **{f"z{i}": "m" for i in (1, 2, 3)}, **{f"delta{i}": "m" for i in (1, 2, 3)}, "z3_meas": "m",
    **{f"q{i}": "C" for i in (1, 2, 3)}, **{f"qh{i}": "C" for i in (1, 2, 3)},
    **{f"v_patch{i}": "V" for i in (1, 2, 3)}, "v_stored": "V",
}
#: Test kinds the tools recognise (for regime labels); any other string is accepted as "other".
TEST_KINDS = ("mbit-a", "mbit-b", "step", "sine", "sweep", "frf", "free", "other")
TERMINALS = ("amplifier", "open_circuit")
_META_KEYS = {
    "format": "format tag, 'mfc-shm-record/1' or 'mfc-shm-frf/1'",
    "test": f"test kind ({', '.join(TEST_KINDS)})",
    "description": "free text",
    "sample_rate_Hz": "sampling rate in Hz (checked against the time column)",
    "inputs": "list of input columns",
    "outputs": "list of measured output columns (default: every other column)",
    "terminal": f"what the patch terminals were connected to ({', '.join(TERMINALS)})",
    "params": "parameter set the test was planned with (informational)",
    "start_time": "ISO 8601 start time",
    "operating_hours": "operating time of the structure when the record was taken (h, >= 0; shm health trends on it)",
    "channels": "per-column tables: model_output, sensor, position_m, noise_std, description",
    "segments": "array of tables: start_s, end_s, label (test regimes)",
    "frf": "frequency-response table: drive, amplitude, amplitude_unit, bias_V",
    "tdms": "TDMS import: group, channels (TDMS channel name -> column name with unit)",
    "provenance": "free-form table (how the record was made)",
    "notes": "free-form table",
}
_CHANNEL_KEYS = {"model_output", "sensor", "position_m", "noise_std", "description"}


class RecordError(InputError):
    """A record file is wrong. The message names the file, where (line/sample, column or key) and why."""

    def __init__(self, file: str | Path, reason: str, *, line: int | None = None, column: str | None = None,
                 key: str | None = None, where: str | None = None) -> None:
        self.file, self.reason, self.line, self.column, self.key = str(file), reason, line, column, key
        parts = [self.file]
        if where is not None:
            parts.append(where)
        elif line is not None:
            parts.append(f"line {line}")
        if column is not None:
            parts.append(f"column '{column}'")
        if key is not None:
            parts.append(f"metadata key '{key}'")
        super().__init__(": ".join([", ".join(parts), reason]))


@dataclass(frozen=True)
class Channel:
    """One column of a record, in SI units. ``name`` is the quantity (``z3``), ``column`` the header (``z3_mm``)."""

    name: str
    column: str
    unit: Unit
    values: np.ndarray
    role: str  # "input" | "output"
    model_output: str | None = None
    sensor: str | None = None
    position_m: float | None = None
    noise_std: float | None = None  # SI
    description: str = ""

    @property
    def si_unit(self) -> str:
        return self.unit.si


@dataclass(frozen=True)
class Segment:
    """A labelled stretch of a test (a regime): ``[start_s, end_s)``."""

    start_s: float
    end_s: float
    label: str


@dataclass(frozen=True)
class Record:
    """A time-domain measurement record (SI units inside)."""

    path: str
    test: str
    t: np.ndarray
    channels: Mapping[str, Channel]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    segments: tuple[Segment, ...] = ()
    terminal: str | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)

    kind = "time"

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.channels[name].values
        except KeyError:
            raise KeyError(f"{self.path}: no channel '{name}' (channels: {', '.join(self.channels)})") from None

    @property
    def name(self) -> str:
        return Path(self.path).stem

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Median sample interval (s)."""
        return float(np.median(np.diff(self.t)))

    @property
    def sample_rate_Hz(self) -> float:
        return 1.0 / self.dt

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def uniform(self) -> bool:
        """True when every interval is within 0.1 % of the median (the usual logger case)."""
        d = np.diff(self.t)
        return bool(np.max(np.abs(d - self.dt)) <= 1e-3 * self.dt)

    def input_matrix(self) -> np.ndarray:
        """The plant's inputs ``(samples, 3)`` [v_ch1 V, v_ch2 V, z0dd m/s^2] at the record's times."""
        u = np.zeros((self.n_samples, N_INPUTS))
        if "va" in self.inputs:
            u[:, U_V_CH1] += self["va"]
            u[:, U_V_CH2] -= self["va"]
        for name, idx in (("v_ch1", U_V_CH1), ("v_ch2", U_V_CH2), ("z0dd", U_Z0DD)):
            if name in self.inputs:
                u[:, idx] += self[name]
        return u

    def input_signals(self) -> InputSignals:
        """The inputs as :class:`plant.InputSignals` on a uniform grid (linearly resampled if the log jitters)."""
        u = self.input_matrix()
        if self.uniform:
            return InputSignals(float(self.t[0]), self.dt, u)
        n = round(self.duration_s / self.dt) + 1
        grid = self.t[0] + self.dt * np.arange(n)
        ug = np.column_stack([np.interp(grid, self.t, u[:, j]) for j in range(N_INPUTS)])
        return InputSignals(float(self.t[0]), self.dt, ug)

    def drive(self) -> tuple[str, str, np.ndarray]:
        """The primary excitation for analysis: ``(name, SI unit, values)``.

        The differential voltage ``va = (v_ch1 - v_ch2)/2`` when the record drives the patches, else the
        base acceleration ``z0dd``. (The common mode of the channels does not bend the laminate.)
        """
        u = self.input_matrix()
        va = 0.5 * (u[:, U_V_CH1] - u[:, U_V_CH2])
        z = u[:, U_Z0DD]
        # compare activity relative to a typical full scale of each input (600 V, 1 g)
        if np.ptp(va) / 600.0 >= np.ptp(z) / 9.80665 and np.ptp(va) > 0:
            return "va", "V", va
        return "z0dd", "m/s^2", z

    def slice(self, start_s: float, end_s: float) -> Record:
        """The part of the record with ``start_s <= t < end_s`` (for train/held-out splits)."""
        k = (self.t >= start_s) & (self.t < end_s)
        if np.count_nonzero(k) < 2:
            raise RecordError(self.path, f"slice [{start_s}, {end_s}) s holds fewer than 2 samples",
                              where=f"t = {self.t[0]:g} .. {self.t[-1]:g} s")
        chans = {n: replace(c, values=c.values[k]) for n, c in self.channels.items()}
        segs = tuple(Segment(max(s.start_s, start_s), min(s.end_s, end_s), s.label) for s in self.segments
                     if s.end_s > start_s and s.start_s < end_s)
        return replace(self, t=self.t[k], channels=MappingProxyType(chans), segments=segs)


@dataclass(frozen=True)
class FrfChannel:
    """Measured frequency response of one output to the drive, SI ratio units (e.g. m/V)."""

    name: str
    unit_si: str
    response: np.ndarray  # complex, output amplitude / drive amplitude, phase relative to the drive
    coherence: np.ndarray | None = None
    model_output: str | None = None


@dataclass(frozen=True)
class FrfRecord:
    """A frequency-response table: stepped-sine amplitude and phase of outputs per frequency."""

    path: str
    frequency_Hz: np.ndarray
    drive: str  # "va" | "v_ch1" | "v_ch2" | "z0dd"
    drive_amplitude: float  # SI (V or m/s^2)
    responses: Mapping[str, FrfChannel]
    bias_V: float = 0.0
    terminal: str | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)
    test: str = "frf"

    kind = "frf"

    @property
    def name(self) -> str:
        return Path(self.path).stem

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.responses)


# ----------------------------------------------------------------------------------------------------------------
# metadata


def _parse_header(path: Path, lines: Sequence[str]) -> dict[str, Any]:
    text = "\n".join(ln[1:] for ln in lines)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RecordError(path, f"header is not valid TOML (each metadata line starts with '#'): {exc}") from None


def sidecar_path(path: str | Path) -> Path:
    """``run1.csv`` -> ``run1.meta.toml`` (also for ``.tdms``)."""
    p = Path(path)
    return p.with_name(p.stem + ".meta.toml")


def _read_sidecar(path: Path) -> dict[str, Any]:
    side = sidecar_path(path)
    if not side.exists():
        return {}
    try:
        return tomllib.loads(side.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise RecordError(side, f"sidecar metadata is not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordError(side, f"cannot read sidecar metadata: {exc}") from None


def _merge_meta(path: Path, header: dict[str, Any], side: dict[str, Any]) -> dict[str, Any]:
    meta = dict(header)
    for key, value in side.items():
        if key in meta and meta[key] != value:
            if isinstance(meta[key], dict) and isinstance(value, dict):
                merged = dict(meta[key])
                for k2, v2 in value.items():
                    if k2 in merged and merged[k2] != v2:
                        raise RecordError(sidecar_path(path), f"conflicts with the file header ({merged[k2]!r} "
                                                             f"vs {v2!r})", key=f"{key}.{k2}")
                    merged[k2] = v2
                meta[key] = merged
                continue
            raise RecordError(sidecar_path(path), f"conflicts with the file header ({meta[key]!r} vs {value!r})",
                              key=key)
        meta[key] = value
    return meta


def _check_meta(file: Path, meta: Mapping[str, Any]) -> None:
    for key in meta:
        if key not in _META_KEYS:
            known = "; ".join(f"{k}: {v}" for k, v in _META_KEYS.items())
            raise RecordError(file, f"unknown key (known keys — {known})", key=key)
    fmt = meta.get("format")
    if fmt is not None and fmt not in (FORMAT, FRF_FORMAT):
        raise RecordError(file, f"unsupported format {fmt!r} (this version reads {FORMAT!r} and {FRF_FORMAT!r})",
                          key="format")
    for key in ("test", "description", "terminal", "params", "start_time"):
        if key in meta and not isinstance(meta[key], str):
            raise RecordError(file, f"expected a string, got {type(meta[key]).__name__} {meta[key]!r}", key=key)
    if "terminal" in meta and meta["terminal"] not in TERMINALS:
        raise RecordError(file, f"unknown terminal {meta['terminal']!r} (allowed: {', '.join(TERMINALS)})",
                          key="terminal")
    if "operating_hours" in meta:
        oh = meta["operating_hours"]
        if isinstance(oh, bool) or not isinstance(oh, (int, float)) or not math.isfinite(oh) or oh < 0:
            raise RecordError(file, f"expected a number of hours >= 0, got {oh!r}", key="operating_hours")
    if "sample_rate_Hz" in meta:
        fs = meta["sample_rate_Hz"]
        if isinstance(fs, bool) or not isinstance(fs, (int, float)) or not math.isfinite(fs) or fs <= 0:
            raise RecordError(file, f"expected a positive number, got {fs!r}", key="sample_rate_Hz")
    for key in ("inputs", "outputs"):
        if key in meta:
            v = meta[key]
            if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
                raise RecordError(file, f"expected a list of column names, got {v!r}", key=key)
    for key in ("channels", "provenance", "notes", "frf", "tdms"):
        if key in meta and not isinstance(meta[key], dict):
            raise RecordError(file, f"expected a table, got {type(meta[key]).__name__}", key=key)
    for col, spec in meta.get("channels", {}).items():
        if not isinstance(spec, dict):
            raise RecordError(file, "expected a table", key=f"channels.{col}")
        for k, v in spec.items():
            if k not in _CHANNEL_KEYS:
                raise RecordError(file, f"unknown key (allowed: {', '.join(sorted(_CHANNEL_KEYS))})",
                                  key=f"channels.{col}.{k}")
            if k in ("position_m", "noise_std") and (isinstance(v, bool) or not isinstance(v, (int, float))
                                                     or not math.isfinite(v) or (k == "noise_std" and v < 0)):
                raise RecordError(file, f"expected a finite{' non-negative' if k == 'noise_std' else ''} number, "
                                        f"got {v!r}", key=f"channels.{col}.{k}")
            if k in ("model_output", "sensor", "description") and not isinstance(v, str):
                raise RecordError(file, f"expected a string, got {v!r}", key=f"channels.{col}.{k}")
    segs = meta.get("segments", [])
    if not isinstance(segs, list):
        raise RecordError(file, "expected an array of tables [[segments]]", key="segments")
    for i, s in enumerate(segs):
        where = f"segments[{i}]"
        if not isinstance(s, dict) or set(s) != {"start_s", "end_s", "label"}:
            raise RecordError(file, "expected a table with exactly start_s, end_s, label", key=where)
        if not all(isinstance(s[k], (int, float)) and not isinstance(s[k], bool) for k in ("start_s", "end_s")):
            raise RecordError(file, "start_s and end_s must be numbers (s)", key=where)
        if not s["end_s"] > s["start_s"]:
            raise RecordError(file, f"end_s ({s['end_s']}) must be after start_s ({s['start_s']})", key=where)
        if not isinstance(s["label"], str) or not s["label"]:
            raise RecordError(file, "label must be a non-empty string", key=where)


# ----------------------------------------------------------------------------------------------------------------
# columns -> record


def _parse_columns(file: Path, names: Sequence[str], line: int | None) -> list[tuple[str, Unit]]:
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


def _build_record(file: Path, columns: Sequence[str], data: np.ndarray, meta: dict[str, Any],
                  locate: Callable[[int], str], time_si: np.ndarray | None = None) -> Record:
    """Validate and assemble. ``data[:, j]`` holds column ``columns[j]`` as written (not yet SI).

    ``locate(k)`` names sample ``k`` for messages (a file line for CSV, a sample index for TDMS). When
    ``time_si`` is given (TDMS waveform timing) there is no time column in ``columns``.
    """
    _check_meta(file, meta)
    header_line = None
    parsed = _parse_columns(file, columns, header_line)
    colnames = list(columns)
    # NaN / Inf
    bad = ~np.isfinite(data)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise RecordError(file, f"value {float(data[k, j])!r} is not finite (NaN/Inf are not allowed; cut the stretch "
                                "out or split the record)", where=locate(int(k)), column=colnames[j])
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
    if t.size < 2:
        raise RecordError(file, f"needs at least 2 samples, found {t.size}")
    d = np.diff(t)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0]) + 1
        raise RecordError(file, f"time is not strictly increasing ({t[k - 1]:.9g} s then {t[k]:.9g} s)",
                          where=locate(k), column=colnames[0] if time_si is None else "time")
    if "sample_rate_Hz" in meta:
        fs = float(meta["sample_rate_Hz"])
        fs_t = 1.0 / float(np.median(d))
        if abs(fs_t - fs) > 0.01 * fs:
            raise RecordError(file, f"sample_rate_Hz = {fs:g} but the time column has {fs_t:.6g} Hz",
                              key="sample_rate_Hz")
    by_col = {c: parsed[j] for j, c in enumerate(colnames)}
    data_cols = colnames[first:]
    chan_meta: dict[str, dict[str, Any]] = meta.get("channels", {})
    for col in chan_meta:
        if col not in by_col:
            raise RecordError(file, f"describes column '{col}', which the record does not have "
                                    f"(columns: {', '.join(colnames)})", key=f"channels.{col}")
    inputs_cols = meta.get("inputs")
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
    outputs_cols = meta.get("outputs")
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
    return Record(
        path=str(file), test=test, t=np.ascontiguousarray(t, dtype=float), channels=MappingProxyType(channels),
        inputs=tuple(by_col[c][0] for c in inputs_cols), outputs=tuple(by_col[c][0] for c in outputs_cols),
        segments=segments, terminal=meta.get("terminal"), meta=MappingProxyType(dict(meta)),
    )


# ----------------------------------------------------------------------------------------------------------------
# CSV


def _read_csv_table(path: Path) -> tuple[dict[str, Any], list[str], np.ndarray, int, list[str]]:
    """Header metadata, column names, data (as written), the file line number of the first data row."""
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Excel, Windows tools) is read past
    except FileNotFoundError:
        raise RecordError(path, "file not found") from None
    except IsADirectoryError:
        raise RecordError(path, "is a directory, not a record file") from None
    except UnicodeDecodeError as exc:
        raise RecordError(path, f"not a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise RecordError(path, f"cannot read: {exc}") from None
    lines = text.splitlines()
    n_head = 0
    while n_head < len(lines) and lines[n_head].startswith("#"):
        n_head += 1
    header_meta = _parse_header(path, lines[:n_head])
    meta = _merge_meta(path, header_meta, _read_sidecar(path))
    if n_head >= len(lines) or not lines[n_head].strip():
        raise RecordError(path, "no column header line (e.g. 'time_s,v_ch1_V,v_ch2_V,z3_m') after the metadata",
                          line=n_head + 1)
    sep = _separator(lines[n_head])
    columns = [c.strip() for c in lines[n_head].split(sep)]
    body = lines[n_head + 1:]
    cut = not text.endswith(("\n", "\r"))
    while body and not body[-1].strip():
        body.pop()
    first_line = n_head + 2
    if not body:
        raise RecordError(path, "no data rows after the column header", line=first_line)
    if cut:
        raise RecordError(path, "the last data row has no end-of-line: the file looks cut off in the middle of a row "
                                "(a logger stopped mid-write?), so its last number may be incomplete; delete the "
                                "partial row, or end the line with a newline if it is complete",
                          line=first_line + len(body) - 1)
    if sep != ",":  # ';' or tab separators: a comma inside a field is a decimal comma
        body = [row.replace(",", ".") for row in body]
    ncol = len(columns)
    try:
        data = np.loadtxt(io.StringIO("\n".join(body)), delimiter=sep, ndmin=2, dtype=float, comments=None)
        if data.shape[1] != ncol:
            raise ValueError("column count")
    except ValueError:
        _diagnose_rows(path, columns, body, first_line, sep)
        raise RecordError(path, "cannot parse the data rows", line=first_line) from None
    return meta, columns, data, first_line, lines[:n_head]


def _separator(column_line: str) -> str:
    """The field separator, from the column line: ',' (the format), or ';' / tab as European spreadsheet exports
    write (their data then may use decimal commas, which are read as decimal points)."""
    if "," in column_line:
        return ","
    for sep in (";", "\t"):
        if sep in column_line:
            return sep
    return ","


def _diagnose_rows(path: Path, columns: list[str], body: list[str], first_line: int, sep: str = ",") -> None:
    """Find the first bad row and raise a precise error (the fast parser only says 'something failed')."""
    ncol = len(columns)
    name = {",": "','", ";": "';'", "\t": "tab"}.get(sep, repr(sep))
    for i, row in enumerate(body):
        line = first_line + i
        fields = row.split(sep)
        if not row.strip():
            raise RecordError(path, "empty line inside the data", line=line)
        if len(fields) != ncol:
            hint = ""
            if sep == "," and len(fields) > ncol:
                hint = ("; decimal commas? write numbers with a '.' decimal point, or separate the fields with ';' "
                        "(then a decimal comma is read as a point)")
            elif sep == "," and ";" in row:
                hint = "; the row is separated by ';' but the column line by ','"
            raise RecordError(path, f"has {len(fields)} fields but the header has {ncol} columns "
                                    f"({', '.join(columns)}; separator {name}){hint}", line=line,
                              column=columns[min(len(fields), ncol) - 1] if len(fields) < ncol else None)
        for j, f in enumerate(fields):
            try:
                float(f)
            except ValueError:
                raise RecordError(path, f"'{f.strip()}' is not a number" if f.strip() else "empty field",
                                  line=line, column=columns[j]) from None


def load_csv_record(path: str | Path) -> Record | FrfRecord:
    path = Path(path)
    meta, columns, data, first_line, _ = _read_csv_table(path)
    if meta.get("format") == FRF_FORMAT or meta.get("test") == "frf" or (columns and columns[0].startswith(
            "frequency_")):
        return _build_frf(path, columns, data, meta, lambda k: f"line {first_line + k}")
    return _build_record(path, columns, data, meta, lambda k: f"line {first_line + k}")


# ----------------------------------------------------------------------------------------------------------------
# TDMS (CompactRIO / LabVIEW logs)


def load_tdms_record(path: str | Path) -> Record:
    """Import a TDMS file as a CompactRIO / LabVIEW logger writes it.

    Channels of one group (``[tdms] group`` in the sidecar, else the only group holding data). Time comes from
    the waveform properties (``wf_increment``, ``wf_start_offset``) or a channel whose column is ``time_<unit>``.
    A channel's column name is: the sidecar mapping ``[tdms.channels] "TDMS name" = "z3_mm"``; else the channel
    name itself when it already ends in a unit (``z3_mm``); else ``<name>_<unit_string property>``. File and group
    properties named like metadata keys (``test``, ``sample_rate_Hz``, ``terminal`` ...) are used as metadata.
    """
    from nptdms import TdmsFile

    path = Path(path)
    # a corrupt file is our RecordError, not a stream of npTDMS reader warnings (its loggers set their own levels)
    quiet = {name: lg for name, lg in logging.root.manager.loggerDict.items()
             if name.startswith("nptdms") and isinstance(lg, logging.Logger)}
    levels = {name: lg.level for name, lg in quiet.items()}
    for lg in quiet.values():
        lg.setLevel(logging.ERROR)
    try:
        tf = TdmsFile.read(str(path))
    except FileNotFoundError:
        raise RecordError(path, "file not found") from None
    except Exception as exc:  # npTDMS raises several types for corrupt files
        raise RecordError(path, f"not a readable TDMS file: {type(exc).__name__}: {exc}") from None
    finally:
        for name, lg in quiet.items():
            lg.setLevel(levels[name])
    side = _read_sidecar(path)
    tdms_meta = side.get("tdms", {})
    if not isinstance(tdms_meta, dict):
        raise RecordError(sidecar_path(path), "expected a table", key="tdms")
    groups = [g for g in tf.groups() if len(g.channels()) > 0]
    want = tdms_meta.get("group")
    if want is not None:
        match = [g for g in groups if g.name == want]
        if not match:
            raise RecordError(path, f"no group '{want}' (groups: {', '.join(g.name for g in groups)})",
                              key="tdms.group")
        group = match[0]
    elif len(groups) == 1:
        group = groups[0]
    elif not groups:
        raise RecordError(path, "the file holds no channel data")
    else:
        raise RecordError(path, f"several groups hold data ({', '.join(g.name for g in groups)}); choose one with "
                                "[tdms] group = \"...\" in the sidecar", key="tdms.group")
    header: dict[str, Any] = {}
    for props in (tf.properties, group.properties):
        for k, v in props.items():
            if k in _META_KEYS and k not in ("channels", "segments", "tdms"):
                header[k] = v.item() if isinstance(v, np.generic) else v
    for k in ("inputs", "outputs"):
        if isinstance(header.get(k), str):  # TDMS properties cannot hold lists: comma-separated
            header[k] = [s.strip() for s in header[k].split(",") if s.strip()]
    meta = _merge_meta(path, header, side)
    mapping = tdms_meta.get("channels", {})
    columns: list[str] = []
    arrays: list[np.ndarray] = []
    time_si = None
    n0 = None
    for ch in group.channels():
        data = np.asarray(ch[:], dtype=float) if ch.data is not None else np.zeros(0)
        if ch.name in mapping:
            col = mapping[ch.name]
        elif split_column(ch.name)[1] is not None:
            col = ch.name
        else:
            us = ch.properties.get("unit_string")
            if us is None:
                raise RecordError(path, "channel name carries no unit and has no 'unit_string' property; map it "
                                        "in the sidecar: [tdms.channels] \"NAME\" = \"quantity_unit\"",
                                  column=ch.name)
            unit = unit_from_string(str(us))
            if unit is None:
                raise RecordError(path, f"unknown unit_string '{us}' (known units: {known_units()})",
                                  column=ch.name)
            col = f"{ch.name.strip().replace(' ', '_')}_{unit.token}"
        if n0 is None:
            n0 = data.size
        elif data.size != n0:
            raise RecordError(path, f"has {data.size} samples but '{group.channels()[0].name}' has {n0} "
                                    "(channels of a record must have equal lengths; a file cut off mid-write "
                                    "ends short in its last channels)", column=ch.name)
        if split_column(col)[0] == "time":
            columns.insert(0, col)
            arrays.insert(0, data)
            continue
        columns.append(col)
        arrays.append(data)
        if time_si is None and "wf_increment" in ch.properties:
            inc = float(ch.properties["wf_increment"])
            if not inc > 0:
                raise RecordError(path, f"wf_increment = {inc!r} must be positive", column=ch.name)
            t0 = float(ch.properties.get("wf_start_offset", 0.0))
            time_si = t0 + inc * np.arange(data.size)
    missing = [k for k in mapping if k not in {c.name for c in group.channels()}]
    if missing:
        raise RecordError(sidecar_path(path), f"maps channel '{missing[0]}', which group '{group.name}' does not have",
                          key="tdms.channels")
    if not columns:
        raise RecordError(path, f"group '{group.name}' holds no channels")
    data2 = np.column_stack(arrays) if arrays else np.zeros((0, 0))
    if columns[0].startswith("time_"):
        time_si = None  # an explicit time channel wins over waveform timing
    elif time_si is None:
        raise RecordError(path, "no time: neither a 'time_<unit>' channel nor waveform timing (wf_increment)")
    return _build_record(path, columns, data2, meta, lambda k: f"sample {k}", time_si=time_si)


def write_tdms_record(record: Record, path: str | Path, group: str = "Measurements") -> Path:
    """Write a record as a cRIO-style TDMS file: one group, waveform timing, ``unit_string`` per channel."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    path = Path(path)
    props = {k: v for k, v in record.meta.items() if isinstance(v, (str, int, float)) and not isinstance(v, bool)}
    props["inputs"] = ",".join(record.channels[n].column for n in record.inputs)
    objs: list[Any] = [RootObject(properties=props), GroupObject(group)]
    for ch in record.channels.values():
        qty = ch.name
        objs.append(ChannelObject(group, qty, ch.unit.from_si(ch.values), properties={
            "unit_string": ch.unit.token.replace("_s2", "/s^2"), "wf_increment": record.dt,
            "wf_start_offset": float(record.t[0])}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs)
    return path


# ----------------------------------------------------------------------------------------------------------------
# frequency-response tables


def _build_frf(file: Path, columns: Sequence[str], data: np.ndarray, meta: dict[str, Any],
               locate: Callable[[int], str]) -> FrfRecord:
    _check_meta(file, meta)
    parsed = _parse_columns(file, columns, None)
    if not parsed or parsed[0][0] != "frequency" or parsed[0][1].si != "Hz":
        raise RecordError(file, "the first column of a frequency-response table must be 'frequency_Hz'",
                          column=columns[0] if columns else None)
    bad = ~np.isfinite(data)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise RecordError(file, f"value {float(data[k, j])!r} is not finite", where=locate(int(k)), column=columns[j])
    f = parsed[0][1].to_si(data[:, 0])
    if np.any(f <= 0):
        k = int(np.flatnonzero(f <= 0)[0])
        raise RecordError(file, f"frequency {float(f[k]):g} Hz must be positive", where=locate(k), column=columns[0])
    d = np.diff(f)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0]) + 1
        raise RecordError(file, "frequencies must be strictly increasing", where=locate(k), column=columns[0])
    frf = meta.get("frf")
    if not isinstance(frf, dict):
        raise RecordError(file, "a frequency-response table needs [frf] with drive, amplitude, amplitude_unit",
                          key="frf")
    for k in frf:
        if k not in ("drive", "amplitude", "amplitude_unit", "bias_V"):
            raise RecordError(file, "unknown key (allowed: drive, amplitude, amplitude_unit, bias_V)", key=f"frf.{k}")
    drive = frf.get("drive")
    if drive not in ("va", "v_ch1", "v_ch2", "z0dd"):
        raise RecordError(file, f"drive must be one of va, v_ch1, v_ch2, z0dd; got {drive!r}", key="frf.drive")
    amp = frf.get("amplitude")
    if isinstance(amp, bool) or not isinstance(amp, (int, float)) or not amp > 0 or not math.isfinite(amp):
        raise RecordError(file, f"amplitude must be a positive number, got {amp!r}", key="frf.amplitude")
    au = unit_from_string(str(frf.get("amplitude_unit", "")))
    if au is None or au.si != INPUT_QUANTITIES[drive]:
        raise RecordError(file, f"amplitude_unit {frf.get('amplitude_unit')!r} is not a unit of {drive} "
                                f"({INPUT_QUANTITIES[drive]})", key="frf.amplitude_unit")
    bias = frf.get("bias_V", 0.0)
    drive_si = INPUT_QUANTITIES[drive]
    amps: dict[str, tuple[int, Unit]] = {}
    phases: dict[str, tuple[int, Unit]] = {}
    cohs: dict[str, int] = {}
    for j, (qty, unit) in enumerate(parsed[1:], start=1):
        if qty.endswith("_amp"):
            out = qty[:-4]
            num, _, den = unit.si.partition("/")
            if not den or den.strip("()") != drive_si:
                raise RecordError(file, f"amplitude unit '{unit.token}' must be an output unit per {drive} unit "
                                        f"(e.g. m_per_V for drive va, V_per_g for z0dd)", column=columns[j])
            exp = KNOWN_QUANTITY_UNITS.get(out)
            if exp is not None and num != exp:
                raise RecordError(file, f"'{out}' is measured in {exp}, not {num}", column=columns[j])
            if np.any(data[:, j] < 0):
                k = int(np.flatnonzero(data[:, j] < 0)[0])
                raise RecordError(file, "amplitude must be non-negative", where=locate(k), column=columns[j])
            amps[out] = (j, unit)
        elif qty.endswith("_phase"):
            if unit.si != "rad":
                raise RecordError(file, f"phase unit must be deg or rad, got '{unit.token}'", column=columns[j])
            phases[qty[:-6]] = (j, unit)
        elif qty.endswith("_coh"):
            cohs[qty[:-4]] = j
        else:
            raise RecordError(file, "frequency-response columns are <output>_amp_<unit>_per_<unit>, "
                                    "<output>_phase_deg and optional <output>_coh_1", column=columns[j])
    if not amps:
        raise RecordError(file, "no amplitude column (e.g. z3_amp_m_per_V)")
    for out in phases:
        if out not in amps:
            raise RecordError(file, f"phase column for '{out}' without an amplitude column",
                              column=columns[phases[out][0]])
    chans_meta = meta.get("channels", {})
    responses: dict[str, FrfChannel] = {}
    for out, (j, unit) in amps.items():
        if out not in phases:
            raise RecordError(file, f"amplitude column for '{out}' without a phase column ({out}_phase_deg)",
                              column=columns[j])
        jp, up = phases[out]
        h = unit.to_si(data[:, j]) * np.exp(1j * up.to_si(data[:, jp]))
        spec = next((v for k, v in chans_meta.items() if split_column(k)[0] in (out, f"{out}_amp")), {})
        responses[out] = FrfChannel(out, unit.si, h, data[:, cohs[out]] if out in cohs else None,
                                    spec.get("model_output"))
    return FrfRecord(path=str(file), frequency_Hz=f, drive=drive, drive_amplitude=float(au.to_si(float(amp))),
                     responses=MappingProxyType(responses), bias_V=float(bias), terminal=meta.get("terminal"),
                     meta=MappingProxyType(dict(meta)))


# ----------------------------------------------------------------------------------------------------------------
# entry points


def load_record(path: str | Path) -> Record | FrfRecord:
    """Load a measurement record: ``.csv`` (time record or frequency-response table) or ``.tdms``.

    Raises :class:`RecordError` naming file, line/sample, column or metadata key, and the reason.
    """
    p = Path(path)
    if p.suffix.lower() == ".tdms":
        return load_tdms_record(p)
    if p.suffix.lower() in (".csv", ".txt"):
        return load_csv_record(p)
    raise RecordError(p, f"unknown record type '{p.suffix}' (expected .csv or .tdms)")


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf") if math.isinf(x) else repr(x)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} {v!r} as TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(k)


def meta_to_toml(meta: Mapping[str, Any]) -> str:
    """Serialise record metadata (scalars, lists, tables, array of tables ``segments``) as TOML text."""
    lines: list[str] = []
    tables: list[tuple[str, Mapping[str, Any]]] = []
    arrays: list[tuple[str, list[Mapping[str, Any]]]] = []
    for k, v in meta.items():
        if isinstance(v, Mapping):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            arrays.append((k, v))
        else:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for name, tab in tables:
        plain = {k: v for k, v in tab.items() if not isinstance(v, Mapping)}
        subs = {k: v for k, v in tab.items() if isinstance(v, Mapping)}
        if plain or not subs:
            lines.append(f"[{_toml_key(name)}]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in plain.items()]
        for k, v in subs.items():
            lines.append(f"[{_toml_key(name)}.{_toml_key(k)}]")
            lines += [f"{_toml_key(k2)} = {_toml_value(v2)}" for k2, v2 in v.items()]
    for name, arr in arrays:
        for item in arr:
            lines.append(f"[[{_toml_key(name)}]]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines)


def write_csv_record(path: str | Path, time_s: np.ndarray, columns: Mapping[str, np.ndarray],
                     meta: Mapping[str, Any]) -> Path:
    """Write a time record: ``columns`` maps column names with units (``z3_m``) to values *in those units*."""
    path = Path(path)
    head = meta_to_toml({"format": FORMAT, **meta})
    names = ["time_s", *columns]
    data = np.column_stack([np.asarray(time_s, float)] + [np.asarray(v, float) for v in columns.values()])
    with path.open("w", encoding="utf-8") as fh:
        fh.write("".join(f"# {ln}\n" for ln in head.splitlines()))
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.10g")
    return path


def record_from_arrays(time_s: np.ndarray, columns: Mapping[str, np.ndarray], meta: Mapping[str, Any],
                      path: str = "<memory>") -> Record:
    """Build (and validate) a record in memory; ``columns`` maps column names with units to values in those
    units, exactly as they would appear in the file."""
    names = ["time_s", *columns]
    data = np.column_stack([np.asarray(time_s, float)] + [np.asarray(v, float) for v in columns.values()])
    return _build_record(Path(path), names, data, {"format": FORMAT, **meta}, lambda k: f"sample {k}")


def write_record(record: Record, path: str | Path) -> Path:
    """Write a record to ``.csv`` (header metadata) or ``.tdms``, each channel in its own column unit."""
    path = Path(path)
    if path.suffix.lower() == ".tdms":
        return write_tdms_record(record, path)
    cols = {ch.column: ch.unit.from_si(ch.values) for ch in record.channels.values()}
    meta = {k: v for k, v in record.meta.items() if k != "format"}
    meta["inputs"] = [record.channels[n].column for n in record.inputs]
    return write_csv_record(path, record.t, cols, meta)


def write_frf_table(path: str | Path, frequency_Hz: np.ndarray, responses: Mapping[str, tuple[np.ndarray, str]],
                    meta: Mapping[str, Any]) -> Path:
    """Write a frequency-response table; ``responses[out] = (complex SI response, ratio unit token)``.

    The ratio unit token is e.g. ``m_per_V``; the complex response must be in the matching SI ratio.
    """
    from workbench.units import lookup_unit

    path = Path(path)
    cols: dict[str, np.ndarray] = {}
    for out, (h, token) in responses.items():
        unit = lookup_unit(token)
        if unit is None:
            raise ValueError(f"unknown ratio unit '{token}'")
        cols[f"{out}_amp_{token}"] = unit.from_si(np.abs(h))
        cols[f"{out}_phase_deg"] = np.degrees(np.unwrap(np.angle(h)))
    head = meta_to_toml({"format": FRF_FORMAT, "test": "frf", **meta})
    data = np.column_stack([np.asarray(frequency_Hz, float), *cols.values()])
    with path.open("w", encoding="utf-8") as fh:
        fh.write("".join(f"# {ln}\n" for ln in head.splitlines()))
        fh.write(",".join(["frequency_Hz", *cols]) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.10g")
    return path


__all__ = [
    "FORMAT",
    "FRF_FORMAT",
    "INPUT_NAMES",
    "Channel",
    "FrfChannel",
    "FrfRecord",
    "Record",
    "RecordError",
    "Segment",
    "load_csv_record",
    "load_record",
    "load_tdms_record",
    "meta_to_toml",
    "record_from_arrays",
    "sidecar_path",
    "write_csv_record",
    "write_frf_table",
    "write_record",
    "write_tdms_record",
]
