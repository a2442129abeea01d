"""Wall-clock timing for the benchmarks and `flatfree bench`: best of several repeats.

On a shared machine noise only ever adds time, so the minimum over repeats is the figure to
report (the median is offered where a spread is wanted).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

__all__ = ["timings", "best_time"]


def timings(fn: Callable[..., Any], *args: Any, repeats: int = 5) -> list[float]:
    """Wall times [s] of ``repeats`` calls ``fn(*args)``."""
    if repeats < 1:
        raise ValueError(f"repeats = {repeats!r}: must be >= 1")
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*args)
        out.append(time.perf_counter() - t0)
    return out


def best_time(fn: Callable[..., Any], *args: Any, repeats: int = 5) -> float:
    """The shortest wall time [s] of ``repeats`` calls ``fn(*args)``."""
    return min(timings(fn, *args, repeats=repeats))
