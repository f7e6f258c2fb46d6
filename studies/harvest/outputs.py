"""The files and the verdict of a harvesting run: CSV tables (charge curve, chunks, audit, charging rate) and one line
on the paper's 10-minute claim."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from reporting.csv_columns import write_csv
from studies.harvest.setup import PAPER_CLAIM_S


def format_duration(seconds: float | None) -> str:
    """A duration for people: s, min, h or days ("never" for None or inf)."""
    if seconds is None or not math.isfinite(seconds):
        return "never"
    if seconds < 120:
        return f"{seconds:.1f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def verdict(run: Any) -> str:
    """One line on the paper's 10-minute claim for this run."""
    t = run.time_to_full_s
    how = "measured" if run.t_full_s is not None else "projected"
    if not math.isfinite(t):
        v = run.projection.stall_voltage_V if run.projection is not None else None
        stall = f" (charging stops at v_b = {v:.3f} V" if v is not None else ""
        if v is not None:
            peak = float(run.chunks["va_peak_V"][-1])
            stall += (f": the patch voltage peak {peak:.3g} V never beats the cell voltage plus "
                      f"{2 * run.setup.v_diode:g} V of diode drop)" if peak < v + 2 * run.setup.v_diode else ")")
        return f"the cell never reaches full{stall}: the paper's 10-minute recharge is NOT reproduced"
    ok = t <= PAPER_CLAIM_S
    return (f"time to full {how}: {format_duration(t)} ({t:.4g} s) — the paper's 10-minute claim is "
            f"{'reproduced' if ok else 'NOT reproduced'}")


def write_outputs(run: Any, out: Path) -> dict[str, str]:
    """The numeric results as CSV (charge curve, chunks, audit, charge rate); returns the written files by role.
    The Fig. 9-style plot is separate (:func:`studies.harvest.figures.plot_charge_curve`), written after them."""
    files: dict[str, str] = {}
    write_csv(out / "charge_curve.csv", {
        "time_s": run.t, "v_bat_V": run.v_bat, "v_bat_term_V": run.v_bat_term, "soc_1": run.soc,
        "v_stored_V": run.v_stored})
    files["charge_curve"] = str(out / "charge_curve.csv")
    ch = run.chunks
    write_csv(out / "chunks.csv", {
        "t_end_s": ch["t_end_s"], "v_bat_V": ch["v_bat_V"], "soc_1": ch["soc"], "i_mean_A": ch["i_mean_A"],
        "p_base_in_W": ch["p_in_W"], "v_stored_peak_V": ch["va_peak_V"], "z3_peak_m": ch["z3_peak_m"]})
    files["chunks"] = str(out / "chunks.csv")
    with (out / "audit.csv").open("w") as fh:
        fh.write("term,energy_J,mean_power_W,side\n")
        for r in run.audit.rows:
            fh.write(f"\"{r.name}\",{r.energy_J:.10g},{r.energy_J / run.audit.duration_s:.10g},{r.side}\n")
        fh.write(f"\"residual (sources - uses)\",{run.audit.residual_J:.10g},"
                 f"{run.audit.residual_J / run.audit.duration_s:.10g},residual\n")
    files["audit"] = str(out / "audit.csv")
    if run.projection is not None:
        c = run.projection.curve
        write_csv(out / "charge_rate.csv", {"q_d_C": c.q_d, "v_oc_V": c.v_oc, "i_mean_A": c.i_mean,
                                            "p_base_in_W": c.p_in_mean, "p_cell_W": c.p_cell_mean})
        files["charge_rate"] = str(out / "charge_rate.csv")
    return files
