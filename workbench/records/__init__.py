"""Records: measured or synthetic time and frequency records in, checked and converted to SI once."""

from __future__ import annotations

from workbench.records._columns import build_record
from workbench.records._io import (
    FrfChannel,
    FrfRecord,
    Segment,
    check_distinct_records,
    gap_notes,
    load_record,
    record_from_arrays,
    write_frf_table,
    write_record,
    write_tdms_record,
)
from workbench.records._types import Record, RecordError

__all__ = [
    "FrfChannel",
    "FrfRecord",
    "Record",
    "RecordError",
    "Segment",
    "build_record",
    "check_distinct_records",
    "gap_notes",
    "load_record",
    "record_from_arrays",
    "write_frf_table",
    "write_record",
    "write_tdms_record",
]
