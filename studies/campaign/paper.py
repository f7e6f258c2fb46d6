"""The seed paper's stated BIT fault probabilities (Sec. 4.2, Fig. 11; words only — the figure is not digitised).

Ranges are fractions; ``(0.2, 0.4)`` pools the 20–30 % and 30–40 % ranges as the paper's sentence does.
"""

from __future__ import annotations

PAPER_FAULT_PROBABILITY: dict[str, tuple[tuple[float, float, float], ...]] = {
    "a": ((0.10, 0.20, 0.83), (0.20, 0.30, 0.94)),
    "b": ((0.00, 0.10, 0.00), (0.20, 0.40, 0.85), (0.40, 0.50, 0.99)),
}
