"""Validation helpers: every bad value raises ``ValueError`` naming the field, value and unit."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "as_real", "real", "real_array", "finite", "positive", "positive_or_inf", "nonnegative",
    "in_range", "whole", "one_of", "boolean", "whole_steps",
]


_F64 = np.dtype(np.float64)


def _fmt(name: str, value, unit: str) -> str:
    u = f" {unit}" if unit and unit != "-" else ""
    return f"{name} = {value!r}{u}"


def as_real(value) -> float | None:
    """``float(value)``, or None when it is not one real number: text (a TOML file's ``"6"``),
    booleans (``true`` is not 1), complex numbers and arrays (``float()`` takes a one-element
    one) are not."""
    if type(value) is not int and (  # an int, the common case after float, goes straight on
            isinstance(value, (str, bytes, bool, np.bool_, complex, np.complexfloating)) or (
            isinstance(value, np.ndarray) and value.ndim != 0)):
        return None
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):  # an int beyond float's range too
        return None


def real_array(name: str, value, unit: str = "") -> np.ndarray:
    """``np.asarray(value, float64)`` for arrays of real numbers; raise ``ValueError`` naming
    ``name`` for anything else: text (``"1.0"``), booleans, complex numbers and object arrays
    (a ``None`` among numbers, which ``float64`` would turn into a silent NaN) are not real
    numbers here. Non-finite values pass: their policy is the caller's."""
    if type(value) is np.ndarray and value.dtype is _F64:
        return value  # the common case, returned as np.asarray would: no copy, no checks
    try:
        a = value if isinstance(value, np.ndarray) else np.asarray(value)
    except ValueError:  # a ragged list: numpy's message does not say which argument
        u = f" [{unit}]" if unit and unit != "-" else ""
        raise ValueError(f"{name}{u}: expected an array of real numbers of one shape, got "
                         f"{value!r:.80}") from None
    if a.dtype.kind not in "iuf":
        shown = _fmt(name, value, unit) if a.size <= 4 else f"{name} (shape {a.shape})"
        raise ValueError(f"{shown}: expected real numbers, got dtype {a.dtype}")
    return np.asarray(a, dtype=np.float64)


def real(name: str, value, unit: str = "") -> float:
    """Return ``float(value)``; raise ``ValueError`` if it is not one real number (:func:`as_real`).
    Non-finite values pass: their policy is the caller's."""
    v = as_real(value)
    if v is None:
        raise ValueError(f"{_fmt(name, value, unit)}: expected a real number")
    return v


def finite(name: str, value, unit: str = "") -> float:
    """Return ``float(value)``; raise ``ValueError`` if it is not a finite real number (text and
    booleans are not numbers here)."""
    v = real(name, value, unit)
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
    v = as_real(value)
    if v is None:
        raise ValueError(f"{_fmt(name, value, unit)}: expected a real number > 0 (inf: no "
                         "limit)")
    if not v > 0.0:  # also NaN
        raise ValueError(f"{_fmt(name, value, unit)}: must be > 0 (inf: no limit)")
    return v


def nonnegative(name: str, value, unit: str = "") -> float:
    """A finite value >= 0."""
    v = finite(name, value, unit)
    if v < 0.0:
        raise ValueError(f"{_fmt(name, value, unit)}: must be >= 0")
    return v


def in_range(name: str, value, lo: float, hi: float, unit: str = "", *,
             lo_open: bool = False) -> float:
    """A finite value with lo <= value <= hi (lo < value with ``lo_open``: the message then
    writes the interval (lo, hi])."""
    v = finite(name, value, unit)
    if not ((lo < v if lo_open else lo <= v) and v <= hi):
        raise ValueError(f"{_fmt(name, value, unit)}: must lie in "
                         f"{'(' if lo_open else '['}{lo}, {hi}]")
    return v


def whole(name: str, value, lo: int, unit: str = "", *, strict: bool = False) -> int:
    """An integer >= ``lo`` (an integral float such as a TOML ``100.0`` too); text, booleans,
    NaN, infinity and fractions raise. ``strict``: only an int or a NumPy integer, an integral
    float raises too (the estimators' sample counts and orders)."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        if value < lo:  # an integer as it is, however large (a float would round it)
            raise ValueError(f"{_fmt(name, value, unit)}: must be an integer >= {lo}")
        return int(value)
    if strict:
        raise ValueError(f"{_fmt(name, value, unit)}: must be an integer >= {lo}, given as an "
                         f"int (not {type(value).__name__})")
    v = as_real(value)
    if v is None or not math.isfinite(v) or v != int(v) or v < lo:
        raise ValueError(f"{_fmt(name, value, unit)}: must be an integer >= {lo}")
    return int(v)


def boolean(name: str, value) -> bool:
    """``value`` if it is a ``bool`` (a TOML ``true``/``false``; not 0/1, not a string), else a
    ``ValueError`` naming ``name`` and the value."""
    if not isinstance(value, bool):
        raise ValueError(f"{name} = {value!r}: must be true or false")
    return value


def one_of(name: str, value, allowed: tuple[int, ...], hint: str = "") -> int:
    """One of the integers ``allowed`` (an order, a mode), as an int; an integral float such as
    a TOML ``2.0`` too. Booleans (NumPy's too: ``np.True_ == 1``), text, NaN and others raise;
    ``hint`` ends the message."""
    v = as_real(value)
    if v is None or v not in allowed:
        raise ValueError(f"{_fmt(name, value, '')}: must be "
                         f"{', '.join(map(str, allowed[:-1]))} or {allowed[-1]}{hint}")
    return int(v)


def whole_steps(seconds: float, dt: float) -> tuple[int, bool]:
    """``seconds`` in whole steps of ``dt`` (both [s]), to the nearest (an exact half to the
    even number, as ``round``), and whether that moved it (by more than 1e-9 of a step): the
    one rule of the delays, sample periods and timing multiples on a clock."""
    n = round(seconds / dt)
    return n, abs(n * dt - seconds) > 1e-9 * dt
