"""Built-in physical effects, one file each: every effect class in every module of this package is registered on
import, and those of role ``"effect"`` form the workbench's library (:func:`plant.effect.library_effects`). A new
library effect is one new file here — nothing else is edited."""

from plant.effect import register_effect_package
from plant.effects.bouc_wen import BoucWenHysteresis
from plant.effects.laminate import LaminateModes
from plant.effects.patch_rc import PatchRC
from plant.effects.piezo_coupling import PiezoCoupling
from plant.effects.terminals import AmplifierDrive, OpenCircuit

register_effect_package(__name__, library=True)

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
