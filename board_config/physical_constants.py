"""Physical constants every layer shares (SI). Declared once here, in the bottom layer, and imported everywhere."""

from __future__ import annotations

#: standard gravity (m/s^2 per g): converts base accelerations given in g
G0: float = 9.80665
