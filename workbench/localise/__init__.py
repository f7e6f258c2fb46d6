"""Localisation: which section of the laminate a misfit comes from (the drive, the residual's spectrum)."""

from __future__ import annotations

from workbench.localise._localise import Localisation, drive_rate, localise, model_features

__all__ = [
    "Localisation",
    "drive_rate",
    "localise",
    "model_features",
]
