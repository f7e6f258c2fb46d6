"""TDMS records (CompactRIO / LabVIEW logs, via npTDMS): imported with sidecar metadata, and written."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np

from workbench.records._columns import build_record
from workbench.records._metadata import META_KEYS, merge_meta, read_sidecar, sidecar_path
from workbench.records._types import Record, RecordError, full_rows
from workbench.records._units import known_units, split_column, unit_from_string


def load_tdms_record(path: str | Path) -> Record:
    """Import a TDMS file as a CompactRIO / LabVIEW logger writes it.

    Channels of one group (``[tdms] group`` in the sidecar, else the only group holding data). Time comes from
    the waveform properties (``wf_increment``, ``wf_start_offset``) or a channel whose column is ``time_<unit>``.
    A channel's column name is: the sidecar mapping ``[tdms.channels] "TDMS name" = "z3_mm"``; else the channel
    name itself when it already ends in a unit (``z3_mm``); else ``<name>_<unit_string property>``. File and group
    properties named like metadata keys (``test``, ``sample_rate_Hz``, ``terminal`` ...) are used as metadata.
    """
    path = Path(path)
    tf = _read_tdms(path)
    side = read_sidecar(path)
    tdms_meta = side.get("tdms", {})
    if not isinstance(tdms_meta, dict):
        raise RecordError(sidecar_path(path), "expected a table", key="tdms")
    group = _data_group(path, tf, tdms_meta.get("group"))
    meta = merge_meta(path, _tdms_header(tf, group), side)
    mapping = tdms_meta.get("channels", {})
    columns, arrays, time_si = _channel_columns(path, group, mapping)
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
    return build_record(path, columns, data2, meta, lambda k: f"sample {k}", time_si=time_si)


def _read_tdms(path: Path) -> Any:
    """The npTDMS file at ``path``; a missing or corrupt file is a :class:`RecordError`, not a stream of npTDMS
    reader warnings (its loggers set their own levels: held at ERROR while reading)."""
    from nptdms import TdmsFile

    quiet = {name: lg for name, lg in logging.root.manager.loggerDict.items()
             if name.startswith("nptdms") and isinstance(lg, logging.Logger)}
    levels = {name: lg.level for name, lg in quiet.items()}
    for lg in quiet.values():
        lg.setLevel(logging.ERROR)
    try:
        return TdmsFile.read(str(path))
    except FileNotFoundError:
        raise RecordError(path, "file not found") from None
    except Exception as exc:  # npTDMS raises several types for corrupt files
        raise RecordError(path, f"not a readable TDMS file: {type(exc).__name__}: {exc}") from None
    finally:
        for name, lg in quiet.items():
            lg.setLevel(levels[name])


def _data_group(path: Path, tf: Any, want: Any) -> Any:
    """The group to read: the sidecar's ``[tdms] group`` (``want``), else the only group holding data."""
    groups = [g for g in tf.groups() if len(g.channels()) > 0]
    if want is not None:
        match = [g for g in groups if g.name == want]
        if not match:
            raise RecordError(path, f"no group '{want}' (groups: {', '.join(g.name for g in groups)})",
                              key="tdms.group")
        return match[0]
    if len(groups) == 1:
        return groups[0]
    if not groups:
        raise RecordError(path, "the file holds no channel data")
    raise RecordError(path, f"several groups hold data ({', '.join(g.name for g in groups)}); choose one with "
                            "[tdms] group = \"...\" in the sidecar", key="tdms.group")


def _tdms_header(tf: Any, group: Any) -> dict[str, Any]:
    """File and group properties named like metadata keys, as metadata (``inputs``/``outputs``: comma-separated,
    since TDMS properties cannot hold lists)."""
    header: dict[str, Any] = {}
    for props in (tf.properties, group.properties):
        for k, v in props.items():
            if k in META_KEYS and k not in ("channels", "segments", "tdms"):
                header[k] = v.item() if isinstance(v, np.generic) else v
    for k in ("inputs", "outputs"):
        if isinstance(header.get(k), str):  # TDMS properties cannot hold lists: comma-separated
            header[k] = [s.strip() for s in header[k].split(",") if s.strip()]
    return header


def _channel_column(path: Path, ch: Any, mapping: dict[str, str]) -> str:
    """The column name of channel ``ch``: the sidecar mapping, else its own name when it ends in a unit, else
    ``<name>_<unit_string>``."""
    if ch.name in mapping:
        return mapping[ch.name]
    if split_column(ch.name)[1] is not None:
        return str(ch.name)
    us = ch.properties.get("unit_string")
    if us is None:
        raise RecordError(path, "channel name carries no unit and has no 'unit_string' property; map it "
                                "in the sidecar: [tdms.channels] \"NAME\" = \"quantity_unit\"",
                          column=ch.name)
    unit = unit_from_string(str(us))
    if unit is None:
        raise RecordError(path, f"unknown unit_string '{us}' (known units: {known_units()})",
                          column=ch.name)
    return f"{ch.name.strip().replace(' ', '_')}_{unit.token}"


def _channel_columns(path: Path, group: Any, mapping: dict[str, str]
                     ) -> tuple[list[str], list[np.ndarray], np.ndarray | None]:
    """The group's channels as (columns, arrays, waveform time in s or None); a time channel goes first."""
    columns: list[str] = []
    arrays: list[np.ndarray] = []
    time_si = None
    n0 = None
    for ch in group.channels():
        data = np.asarray(ch[:], dtype=float) if ch.data is not None else np.zeros(0)
        col = _channel_column(path, ch, mapping)
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
    return columns, arrays, time_si


def write_tdms_record(record: Record, path: str | Path, group: str = "Measurements") -> Path:
    """Write a record as a cRIO-style TDMS file: one group, waveform timing, ``unit_string`` per channel; lost
    samples as NaN with the file property ``missing = "nan"``."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter


    path = Path(path)
    props = {k: v for k, v in record.meta.items() if isinstance(v, (str, int, float)) and not isinstance(v, bool)}
    props["inputs"] = ",".join(record.channels[n].column for n in record.inputs)
    t, si = full_rows(record)  # lost samples as NaN, the LabVIEW way of a gap (marked: missing = "nan")
    if record.gaps:
        props["missing"] = "nan"
    objs: list[Any] = [RootObject(properties=props), GroupObject(group)]
    dt = float(np.median(np.diff(t)))
    for ch in record.channels.values():
        qty = ch.name
        objs.append(ChannelObject(group, qty, ch.unit.from_si(si[qty]), properties={
            "unit_string": ch.unit.token.replace("_s2", "/s^2"), "wf_increment": dt,
            "wf_start_offset": float(t[0])}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs)
    return path
