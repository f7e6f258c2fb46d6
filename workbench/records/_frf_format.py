"""Frequency-response tables (``mfc-shm-frf/1``): validated into an :class:`FrfRecord`, and written."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from workbench.records._columns import parse_columns
from workbench.records._metadata import check_meta, meta_to_toml
from workbench.records._types import (
    FRF_FORMAT,
    INPUT_QUANTITIES,
    KNOWN_QUANTITY_UNITS,
    FrfChannel,
    FrfRecord,
    RecordError,
)
from workbench.records._units import Unit, split_column, unit_from_string


def build_frf(file: Path, columns: Sequence[str], data: np.ndarray, meta: dict[str, Any],
              locate: Callable[[int], str]) -> FrfRecord:
    """Validate and assemble a frequency-response table (``data[:, j]`` holds column ``columns[j]`` as written;
    ``locate(k)`` names row ``k`` for messages)."""
    check_meta(file, meta)
    parsed = parse_columns(file, columns, None)
    if not parsed or parsed[0][0] != "frequency" or parsed[0][1].si != "Hz":
        raise RecordError(file, "the first column of a frequency-response table must be 'frequency_Hz'",
                          column=columns[0] if columns else None)
    f = _frequencies(file, columns, data, parsed[0][1], locate)
    drive, amp, au, bias = _frf_drive(file, meta)
    amps, phases, cohs = _response_columns(file, columns, data, parsed, INPUT_QUANTITIES[drive], drive, locate)
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
        spec: dict[str, Any] = next((v for k, v in chans_meta.items() if split_column(k)[0] in (out, f"{out}_amp")), {})
        responses[out] = FrfChannel(out, unit.si, h, data[:, cohs[out]] if out in cohs else None,
                                    spec.get("model_output"))
    return FrfRecord(path=str(file), frequency_Hz=f, drive=drive, drive_amplitude=float(au.to_si(float(amp))),
                     responses=MappingProxyType(responses), bias_V=float(bias), terminal=meta.get("terminal"),
                     meta=MappingProxyType(dict(meta)))


def _frequencies(file: Path, columns: Sequence[str], data: np.ndarray, unit: Unit,
                 locate: Callable[[int], str]) -> np.ndarray:
    """The frequency column in Hz: every value finite (the whole table's), positive and strictly increasing."""
    bad = ~np.isfinite(data)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise RecordError(file, f"value {float(data[k, j])!r} is not finite", where=locate(int(k)), column=columns[j])
    f = unit.to_si(data[:, 0])
    if np.any(f <= 0):
        k = int(np.flatnonzero(f <= 0)[0])
        raise RecordError(file, f"frequency {float(f[k]):g} Hz must be positive", where=locate(k), column=columns[0])
    d = np.diff(f)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0]) + 1
        raise RecordError(file, "frequencies must be strictly increasing", where=locate(k), column=columns[0])
    return f


def _frf_drive(file: Path, meta: dict[str, Any]) -> tuple[str, float, Unit, Any]:
    """The ``[frf]`` table checked: (drive quantity, amplitude as written, its unit, bias_V as written)."""
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
    return drive, amp, au, frf.get("bias_V", 0.0)


def _response_columns(file: Path, columns: Sequence[str], data: np.ndarray, parsed: list[tuple[str, Unit]],
                      drive_si: str, drive: str, locate: Callable[[int], str]
                      ) -> tuple[dict[str, tuple[int, Unit]], dict[str, tuple[int, Unit]], dict[str, int]]:
    """The response columns by output: amplitudes and phases as (column index, unit), coherences as index."""
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
    return amps, phases, cohs


def write_frf_table(path: str | Path, frequency_Hz: np.ndarray, responses: Mapping[str, tuple[np.ndarray, str]],
                    meta: Mapping[str, Any]) -> Path:
    """Write a frequency-response table; ``responses[out] = (complex SI response, ratio unit token)``.

    The ratio unit token is e.g. ``m_per_V``; the complex response must be in the matching SI ratio.
    """
    from workbench.records._units import lookup_unit

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
