"""Challenges with hidden truth: the hidden-effect sweep and the discovery/damage challenge."""

from __future__ import annotations

__all__ = [
]
