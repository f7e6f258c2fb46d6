"""Record metadata: the keys a record may carry, the sidecar ``<stem>.meta.toml``, merging it with a file's
header, validating it, and writing it as TOML."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from board_config.toml_writer import toml_document
from workbench.records._types import FORMAT, FRF_FORMAT, TERMINALS, TEST_KINDS, RecordError

META_KEYS = {
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
    "missing": "how lost samples are marked: 'empty' (an empty cell, CSV) or 'nan' (a NaN value, as LabVIEW "
               "writes a gap); without it an empty cell or a NaN is an error",
}
#: values of the ``missing`` key (docs/records.md, "Lost samples")
MISSING_MARKS = ("empty", "nan")
_CHANNEL_KEYS = {"model_output", "sensor", "position_m", "noise_std", "description"}


def sidecar_path(path: str | Path) -> Path:
    """``run1.csv`` -> ``run1.meta.toml`` (also for ``.tdms``)."""
    p = Path(path)
    return p.with_name(p.stem + ".meta.toml")


def read_sidecar(path: Path) -> dict[str, Any]:
    side = sidecar_path(path)
    if not side.exists():
        return {}
    try:
        return tomllib.loads(side.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise RecordError(side, f"sidecar metadata is not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordError(side, f"cannot read sidecar metadata: {exc}") from None


def merge_meta(path: Path, header: dict[str, Any], side: dict[str, Any]) -> dict[str, Any]:
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


def check_meta(file: Path, meta: Mapping[str, Any]) -> None:
    for key in meta:
        if key not in META_KEYS:
            known = "; ".join(f"{k}: {v}" for k, v in META_KEYS.items())
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
    if "missing" in meta and meta["missing"] not in MISSING_MARKS:
        raise RecordError(file, f"unknown mark {meta['missing']!r} for lost samples (allowed: "
                                f"{', '.join(MISSING_MARKS)})", key="missing")
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


def meta_to_toml(meta: Mapping[str, Any]) -> str:
    """Serialise record metadata (scalars, lists, tables, array of tables ``segments``) as TOML text."""
    return toml_document(meta)
