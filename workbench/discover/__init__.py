"""Discovery of a term no library effect has: a dictionary of forms, sparse search, the emitted effect."""

from __future__ import annotations

from workbench.discover._dictionary import build_dictionary
from workbench.discover._dictionary_code import dictionary_parameter_names, dictionary_source
from workbench.discover._dictionary_effect import generated_effect, signal_scales
from workbench.discover._effect_writer import formula, parameter_names
from workbench.discover._gates import TIME_GATES
from workbench.discover._onset import change_point, event_onset
from workbench.discover._pipeline import describe_units, discover, load_emitted
from workbench.discover._results import in_one_sentence

__all__ = [
    "TIME_GATES",
    "build_dictionary",
    "change_point",
    "describe_units",
    "dictionary_parameter_names",
    "dictionary_source",
    "discover",
    "event_onset",
    "formula",
    "generated_effect",
    "in_one_sentence",
    "load_emitted",
    "parameter_names",
    "signal_scales",
]
