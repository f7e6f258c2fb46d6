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
its unit as a suffix (:mod:`workbench.records._units`); the rest are numbers. Metadata may also sit in a sidecar
``<stem>.meta.toml`` beside the data file (CSV or TDMS). Values are converted to SI at load time.

Every problem is a :class:`RecordError` naming the file, the line (or sample) and column, and the reason.

This module holds the entry points (:func:`load_record`, :func:`write_record`, :func:`record_from_arrays`) and
re-exports the rest, which lives in one module per concern: :mod:`workbench.records._types` (what a record is),
:mod:`workbench.records._metadata` (keys, sidecar, validation, TOML), :mod:`workbench.records._columns` (columns ->
validated record), :mod:`workbench.records._csv_format`,
:mod:`workbench.records._tdms_format` and :mod:`workbench.records._frf_format`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from plant.layout import INPUT_NAMES
from workbench.records._columns import build_record
from workbench.records._csv_format import load_csv_record, write_csv_record
from workbench.records._frf_format import write_frf_table
from workbench.records._metadata import meta_to_toml, sidecar_path
from workbench.records._tdms_format import load_tdms_record, write_tdms_record
from workbench.records._types import (
    FORMAT,
    FRF_FORMAT,
    INPUT_QUANTITIES,
    KNOWN_QUANTITY_UNITS,
    TERMINALS,
    TEST_KINDS,
    Channel,
    FrfChannel,
    FrfRecord,
    Gap,
    Record,
    RecordError,
    Segment,
    full_rows,
)


def load_record(path: str | Path) -> Record | FrfRecord:
    """Load a measurement record by its suffix (:data:`RECORD_LOADERS`): ``.csv`` (time record or frequency-response
    table) or ``.tdms``.

    Raises :class:`RecordError` naming file, line/sample, column or metadata key, and the reason.
    """
    p = Path(path)
    loader = RECORD_LOADERS.get(p.suffix.lower())
    if loader is None:
        raise RecordError(p, f"unknown record type '{p.suffix}' (expected {' or '.join(RECORD_LOADERS)})")
    return loader(p)


#: the record readers by file suffix (lower case): a new format is one module ``workbench/record_<fmt>.py`` and one
#: entry here (docs/architecture.md, "Recipe: a new record format")
RECORD_LOADERS: dict[str, Callable[[Path], Record | FrfRecord]] = {
    ".csv": load_csv_record,
    ".txt": load_csv_record,
    ".tdms": load_tdms_record,
}


def check_distinct_records(paths: Sequence[str | Path]) -> None:
    """Refuse one record given twice — the same file (resolved path) or a copy (same bytes): with held-out records
    one copy would be training and the other held-out data (a held-out score that proves nothing), and with
    held-out blocks the record would count twice. :class:`RecordError` names both."""
    seen_path: dict[Path, str] = {}
    seen_hash: dict[str, str] = {}
    for raw in paths:
        p = Path(raw)
        try:
            resolved = p.resolve()
            digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        except OSError:
            continue  # unreadable: load_record names it
        twin = seen_path.get(resolved) or (seen_hash.get(digest) if digest else None)
        if twin is not None:
            how = "the same file as" if resolved in seen_path else "a copy (the same content) of"
            raise RecordError(p, f"is {how} record '{twin}' given before: one record cannot be both training and "
                                 "held-out data (or count twice); give each record once")
        seen_path[resolved] = str(raw)
        if digest:
            seen_hash[digest] = str(raw)


def record_from_arrays(time_s: np.ndarray, columns: Mapping[str, np.ndarray], meta: Mapping[str, Any],
                       path: str = "<memory>") -> Record:
    """Build (and validate) a record in memory; ``columns`` maps column names with units to values in those
    units, exactly as they would appear in the file. With ``meta["missing"]`` set (``"empty"`` or ``"nan"``) a
    NaN marks a lost sample (docs/records.md, "Lost samples"); without it a NaN is an error."""
    names = ["time_s", *columns]
    data = np.column_stack([np.asarray(time_s, float)] + [np.asarray(v, float) for v in columns.values()])
    lost = np.isnan(data) if "missing" in meta else None
    return build_record(Path(path), names, data, {"format": FORMAT, **meta}, lambda k: f"sample {k}", lost=lost)


def gap_notes(records) -> list[str]:
    """One sentence per record that lost samples (``Record.gap_note``), for the commands to show."""
    return [r.gap_note() for r in records if getattr(r, "gaps", ())]


def write_record(record: Record, path: str | Path) -> Path:
    """Write a record to ``.csv`` (header metadata) or ``.tdms``, each channel in its own column unit."""
    path = Path(path)
    if path.suffix.lower() == ".tdms":
        return write_tdms_record(record, path)
    t, si = full_rows(record)
    cols = {ch.column: ch.unit.from_si(si[n]) for n, ch in record.channels.items()}
    meta = {k: v for k, v in record.meta.items() if k != "format"}
    if record.gaps and "missing" not in meta:
        meta["missing"] = "empty"
    meta["inputs"] = [record.channels[n].column for n in record.inputs]
    return write_csv_record(path, t, cols, meta)


__all__ = [
    "FORMAT",
    "FRF_FORMAT",
    "INPUT_NAMES",
    "INPUT_QUANTITIES",
    "KNOWN_QUANTITY_UNITS",
    "TERMINALS",
    "TEST_KINDS",
    "Channel",
    "FrfChannel",
    "FrfRecord",
    "Gap",
    "Record",
    "RecordError",
    "Segment",
    "check_distinct_records",
    "full_rows",
    "gap_notes",
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
