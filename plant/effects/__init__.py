"""Built-in physical effects. Each is one file; registering it here is the only other edit."""

from plant.effect import register_effect
from plant.effects.bouc_wen import BoucWenHysteresis
from plant.effects.laminate import LaminateModes
from plant.effects.patch_rc import PatchRC
from plant.effects.piezo_coupling import PiezoCoupling
from plant.effects.terminals import AmplifierDrive, OpenCircuit

for _cls in (LaminateModes, PatchRC, BoucWenHysteresis, PiezoCoupling, AmplifierDrive, OpenCircuit):
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
