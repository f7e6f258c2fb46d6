"""The harvesting study (seed paper Sec. 3.3, Fig. 9): charge the cell from base vibration, the time to full charge
(measured or projected), the power audit, and Eq. 8's closed forms.

Modules: :mod:`.setup` (the experiment, validated), :mod:`.run` (the chunked run), :mod:`.audit` (the energy
books), :mod:`.projection` (time to full when a run does not get there), :mod:`.requirements` (what a full recharge
would take: Eq. 8, power bounds), :mod:`.outputs` (CSV files, the verdict line), :mod:`.figures` (Fig. 9),
:mod:`.reference` (an independent plain-Python statement of the model for ``scipy.integrate.solve_ivp``: the tests'
check and the benchmark's baseline).
"""

from studies.harvest.audit import AuditRow, PowerAudit, power_audit
from studies.harvest.projection import (
    ChargeRateCurve,
    Projection,
    charge_rate_curve,
    project_time_to_full,
    slowest_decay_time,
)
from studies.harvest.requirements import (
    eq8_required_amplitude,
    eq8_time_to_full,
    open_circuit_base_power,
    required_mean_power,
)
from studies.harvest.run import HarvestRun, run_harvest
from studies.harvest.setup import (
    ACCEL_RANGE_G,
    AUDIT_TOLERANCE,
    COUPLINGS,
    DURATION_RANGE_S,
    FREQ_RANGE_HZ,
    I_BOARD_RANGE_A,
    PAPER_CLAIM_S,
    PAPER_GAIN_V_PER_G,
    R_INT_RANGE_OHM,
    HarvestSetup,
    step_cap,
)

__all__ = [
    "ACCEL_RANGE_G",
    "AUDIT_TOLERANCE",
    "COUPLINGS",
    "DURATION_RANGE_S",
    "FREQ_RANGE_HZ",
    "I_BOARD_RANGE_A",
    "PAPER_CLAIM_S",
    "PAPER_GAIN_V_PER_G",
    "R_INT_RANGE_OHM",
    "AuditRow",
    "ChargeRateCurve",
    "HarvestRun",
    "HarvestSetup",
    "PowerAudit",
    "Projection",
    "charge_rate_curve",
    "eq8_required_amplitude",
    "eq8_time_to_full",
    "open_circuit_base_power",
    "power_audit",
    "project_time_to_full",
    "required_mean_power",
    "run_harvest",
    "slowest_decay_time",
    "step_cap",
]
