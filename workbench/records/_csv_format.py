"""CSV records: a TOML header in ``#`` lines (or a sidecar), a column line with units, numbers; read and written."""

from __future__ import annotations

import io
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from workbench.records._columns import build_record
from workbench.records._frf_format import build_frf
from workbench.records._metadata import merge_meta, meta_to_toml, read_sidecar
from workbench.records._types import FORMAT, FRF_FORMAT, FrfRecord, Record, RecordError


def _parse_header(path: Path, lines: Sequence[str]) -> dict[str, Any]:
    text = "\n".join(ln[1:] for ln in lines)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RecordError(path, f"header is not valid TOML (each metadata line starts with '#'): {exc}") from None


def _read_csv_table(path: Path) -> tuple[dict[str, Any], list[str], np.ndarray, int, list[str], np.ndarray | None]:
    """Header metadata, column names, data (as written), the file line number of the first data row, the header
    lines and (with ``missing = "empty"``) the mask of empty cells (lost samples)."""
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
    meta = merge_meta(path, header_meta, read_sidecar(path))
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
    lost = None
    if meta.get("missing") == "empty" and any(_has_empty_cell(row, sep) for row in body):
        body, lost = _mark_empty_cells(body, sep, ncol)
    try:
        data = np.loadtxt(io.StringIO("\n".join(body)), delimiter=sep, ndmin=2, dtype=float, comments=None)
        if data.shape[1] != ncol:
            raise ValueError("column count")
    except ValueError:
        _diagnose_rows(path, columns, body, first_line, sep)
        raise RecordError(path, "cannot parse the data rows", line=first_line) from None
    if lost is not None:
        data[lost] = np.nan
    return meta, columns, data, first_line, lines[:n_head], lost


def _has_empty_cell(row: str, sep: str) -> bool:
    fields = row.split(sep)
    return any(not f.strip() for f in fields) and bool(row.strip())


def _mark_empty_cells(body: list[str], sep: str, ncol: int) -> tuple[list[str], np.ndarray]:
    """Rows with each empty cell (a lost sample) filled with 0 for the parser, and the mask of those cells. A row
    with another number of fields is left as it is (the parser names it)."""
    mask = np.zeros((len(body), ncol), bool)
    out = list(body)
    for i, row in enumerate(body):
        fields = row.split(sep)
        if len(fields) != ncol or not row.strip():
            continue
        empty = [not f.strip() for f in fields]
        if any(empty):
            mask[i] = empty
            out[i] = sep.join("0" if e else f for f, e in zip(fields, empty))
    return out, mask


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
                raise RecordError(path, f"'{f.strip()}' is not a number" if f.strip() else
                                  "empty field (a lost sample? mark lost samples with missing = \"empty\" in the "
                                  "header: docs/records.md, Lost samples)", line=line, column=columns[j]) from None


def load_csv_record(path: str | Path) -> Record | FrfRecord:
    path = Path(path)
    meta, columns, data, first_line, _, lost = _read_csv_table(path)
    if meta.get("format") == FRF_FORMAT or meta.get("test") == "frf" or (columns and columns[0].startswith(
            "frequency_")):
        return build_frf(path, columns, data, meta, lambda k: f"line {first_line + k}")
    return build_record(path, columns, data, meta, lambda k: f"line {first_line + k}", lost=lost)


def write_csv_record(path: str | Path, time_s: np.ndarray, columns: Mapping[str, np.ndarray],
                     meta: Mapping[str, Any]) -> Path:
    """Write a time record: ``columns`` maps column names with units (``z3_m``) to values *in those units*.

    With ``meta["missing"] = "empty"`` a NaN value (a lost sample) is written as an empty cell; with ``"nan"``
    as ``nan``."""
    path = Path(path)
    head = meta_to_toml({"format": FORMAT, **meta})
    names = ["time_s", *columns]
    data = np.column_stack([np.asarray(time_s, float)] + [np.asarray(v, float) for v in columns.values()])
    with path.open("w", encoding="utf-8") as fh:
        fh.write("".join(f"# {ln}\n" for ln in head.splitlines()))
        fh.write(",".join(names) + "\n")
        if meta.get("missing") == "empty" and np.isnan(data).any():
            for row in data:
                fh.write(",".join("" if v != v else f"{v:.10g}" for v in row) + "\n")
        else:
            np.savetxt(fh, data, delimiter=",", fmt="%.10g")
    return path
