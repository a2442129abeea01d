"""Validation helpers: every bad value raises ``ValueError`` naming the field, value and unit."""

from __future__ import annotations

import math

__all__ = ["finite", "positive", "positive_or_inf", "nonnegative", "in_range"]


def _fmt(name: str, value, unit: str) -> str:
    u = f" {unit}" if unit and unit != "-" else ""
    return f"{name} = {value!r}{u}"


def finite(name: str, value, unit: str = "") -> float:
    """Return ``float(value)``; raise ``ValueError`` if it is not a finite real number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{_fmt(name, value, unit)}: expected a real number") from None
    if not math.isfinite(v):
        raise ValueError(f"{_fmt(name, value, unit)}: must be finite")
    return v


def positive(name: str, value, unit: str = "") -> float:
    """A finite value > 0."""
    v = finite(name, value, unit)
    if v <= 0.0:
        raise ValueError(f"{_fmt(name, value, unit)}: must be > 0")
    return v


def positive_or_inf(name: str, value, unit: str = "") -> float:
    """A value > 0, ``inf`` allowed (an absent limit); NaN, <= 0 or not a number raise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{_fmt(name, value, unit)}: expected a real number > 0 (inf: no "
                         "limit)") from None
    if not v > 0.0:  # also NaN
        raise ValueError(f"{_fmt(name, value, unit)}: must be > 0 (inf: no limit)")
    return v


def nonnegative(name: str, value, unit: str = "") -> float:
    """A finite value >= 0."""
    v = finite(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{_fmt(name, value, unit)}: must be >= 0")
    return v


def in_range(name: str, value, lo: float, hi: float, unit: str = "") -> float:
    """A finite value with lo <= value <= hi."""
    v = finite(name, value, unit)
    if not (lo <= v <= hi):
        raise ValueError(f"{_fmt(name, value, unit)}: must lie in [{lo}, {hi}]")
    return v
