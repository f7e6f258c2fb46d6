"""The power audit of a harvesting run: every energy term integrated by the same integrator as the dynamics (extra
states of the terminal), stored energies from the state; the books must close (coupled), or show how much energy
Eq. 8 creates (paper)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plant.battery import TheveninBattery
from plant.effects.harvesting import ENERGY_ACCUMULATORS
from plant.model import PlantModel
from studies.harvest.setup import AUDIT_TOLERANCE


@dataclass(frozen=True)
class AuditRow:
    """One line of the audit: ``side`` is "source", "use" (losses, delivered, stored) or "memo" (not summed)."""

    name: str
    energy_J: float
    side: str
    note: str = ""


@dataclass
class PowerAudit:
    """Energy books of a run: sources = uses + residual. See :func:`power_audit`."""

    duration_s: float
    coupling: str
    rows: list[AuditRow]
    residual_J: float
    relative_residual: float
    battery_crosscheck_J: float  # E_battery accumulator minus the OCV-curve state function
    energy_from_nowhere_J: float  # paper: energy the cell took from patches that never delivered it

    @property
    def sources_J(self) -> float:
        return float(sum(r.energy_J for r in self.rows if r.side == "source"))

    @property
    def uses_J(self) -> float:
        return float(sum(r.energy_J for r in self.rows if r.side == "use"))

    def closes(self, tolerance: float = AUDIT_TOLERANCE) -> bool:
        return bool(abs(self.relative_residual) <= tolerance)

    def row(self, name: str) -> AuditRow:
        for r in self.rows:
            if r.name == name:
                return r
        raise KeyError(f"no audit row '{name}' (rows: {', '.join(r.name for r in self.rows)})")

    def as_dict(self) -> dict[str, Any]:  # JSON at the edge (harvest_summary.json's audit)
        return {
            "duration_s": self.duration_s, "coupling": self.coupling,
            "rows": [{"name": r.name, "energy_J": r.energy_J, "mean_power_W": r.energy_J / self.duration_s,
                      "side": r.side, "note": r.note} for r in self.rows],
            "sources_J": self.sources_J, "uses_J": self.uses_J, "residual_J": self.residual_J,
            "relative_residual": self.relative_residual, "closes_within_1pct": self.closes(),
            "battery_crosscheck_J": self.battery_crosscheck_J, "energy_from_nowhere_J": self.energy_from_nowhere_J,
        }

    def table(self) -> str:
        """Plain-text audit table (energies in J and mean powers in W)."""
        lines = [f"{'term':<52} {'energy J':>12} {'mean power W':>13}  side"]
        for r in self.rows:
            lines.append(f"{r.name:<52} {r.energy_J:>12.4e} {r.energy_J / self.duration_s:>13.4e}  {r.side}")
        lines.append(f"{'sources - uses (residual)':<52} {self.residual_J:>12.4e} "
                     f"{self.residual_J / self.duration_s:>13.4e}  {self.relative_residual:+.3%} of sources")
        return "\n".join(lines)


def power_audit(model: PlantModel, battery: TheveninBattery, x_start: np.ndarray, x_end: np.ndarray,
                e_stored_start: tuple[float, float], e_stored_end: tuple[float, float], duration: float,
                coupling: str) -> PowerAudit:
    """Close the books between two states of a harvesting model.

    Sources: base power in (relative frame, ``-z0'' sum m_j z_j'``), the Bouc-Wen part of the piezo work (the model's
    hysteresis is not guaranteed passive, so it is booked with its sign), net work of any other added effects.
    Uses: structural damping, ``R_ep``, bridge diodes, charge controller, ``R_bint``, board load, chemical energy into
    the cell, change of mechanical (kinetic + elastic) and electrical (``C_ep``) energy.
    ``e_stored_*`` = (E_mech, E_elec) in J.
    """
    idx = {n: model.state_names.index(n) for n in ENERGY_ACCUMULATORS}
    e = {n: float(x_end[i] - x_start[i]) for n, i in idx.items()}
    so = model.state_names.index("bat_qd")
    d_mech = float(e_stored_end[0] - e_stored_start[0])
    d_elec = float(e_stored_end[1] - e_stored_start[1])
    rows = [
        AuditRow("base excitation power in (relative frame)", e["E_base_in"], "source", "-z0'' * sum m_j z_j'"),
        AuditRow("Bouc-Wen hysteresis work on the laminate", e["E_hysteresis"], "source",
                 "theta (q_h - q) delta' / C_ep; either sign"),
        AuditRow("other added effects (net work)", e["E_other_effects"], "source", "0 for the nominal model"),
        AuditRow("structural damping c_i", e["E_damping"], "use"),
        AuditRow("patch resistance R_ep", e["E_R_ep"], "use"),
        AuditRow("bridge diodes", e["E_diodes"], "use"),
        AuditRow("charge controller (no charging past full)", e["E_controller"], "use"),
        AuditRow("cell internal resistance R_bint", e["E_R_bint"], "use"),
        AuditRow("board load", e["E_board"], "use"),
        AuditRow("chemical energy into the cell", e["E_battery"], "use", "integral of v_oc * i_bat"),
        AuditRow("change of mechanical energy (kinetic + elastic)", d_mech, "use"),
        AuditRow("change of electrical energy in C_ep", d_elec, "use"),
        AuditRow("memo: drawn by the bridge from the patch terminals", e["E_rectifier_in"], "memo",
                 "paper mode: the patches never deliver it"),
    ]
    sources = sum(r.energy_J for r in rows if r.side == "source")
    uses = sum(r.energy_J for r in rows if r.side == "use")
    residual = sources - uses
    positive_sources = sum(max(r.energy_J, 0.0) for r in rows if r.side == "source")
    gross = sum(abs(r.energy_J) for r in rows if r.side != "memo")
    scale = positive_sources if positive_sources > 0 else gross
    rel = residual / scale if scale > 0 else 0.0
    state_fn = battery.chemical_energy(float(x_start[so]), float(x_end[so]))
    return PowerAudit(
        duration_s=float(duration), coupling=coupling, rows=rows, residual_J=float(residual),
        relative_residual=float(rel), battery_crosscheck_J=float(e["E_battery"] - state_fn),
        energy_from_nowhere_J=float(e["E_rectifier_in"]) if coupling == "paper" else 0.0,
    )


