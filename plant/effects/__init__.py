"""Built-in physical effects. Each is one file; registering it here is the only other edit."""

from plant.effect import register_effect
from plant.effects.air_damping import QuadraticAirDamping
from plant.effects.amplifier_current_limit import AmplifierCurrentLimit
from plant.effects.bouc_wen import BoucWenHysteresis
from plant.effects.dielectric_leakage import DielectricLeakage
from plant.effects.geometric_stiffening import GeometricStiffening
from plant.effects.harvesting import HarvestCoupled, HarvestPaper
from plant.effects.laminate import LaminateModes
from plant.effects.laser_sensor import LaserSensor
from plant.effects.patch_rc import PatchRC
from plant.effects.piezo_coupling import PiezoCoupling
from plant.effects.piezo_creep import PiezoCreep
from plant.effects.root_compliance import RootClampCompliance
from plant.effects.terminals import AmplifierDrive, OpenCircuit
from plant.effects.thermal_drift import PiezoThermalDrift

for _cls in (LaminateModes, PatchRC, BoucWenHysteresis, PiezoCoupling, AmplifierDrive, OpenCircuit,
             PiezoCreep, GeometricStiffening, QuadraticAirDamping, DielectricLeakage, AmplifierCurrentLimit,
             LaserSensor, RootClampCompliance, PiezoThermalDrift, HarvestCoupled, HarvestPaper):
    register_effect(_cls)

#: The nominal model of the seed paper, in evaluation order.
NOMINAL_EFFECTS: tuple[str, ...] = ("laminate", "patch_rc", "bouc_wen", "piezo_coupling")

__all__ = [
    "NOMINAL_EFFECTS",
    "AmplifierDrive",
    "BoucWenHysteresis",
    "LaminateModes",
    "OpenCircuit",
    "PatchRC",
    "PiezoCoupling",
]
