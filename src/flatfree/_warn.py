"""Warnings that point at the user's line: :func:`warn`.

A library warning is shown with the line that called into the library, the first frame outside
it. ``warnings.warn``'s ``stacklevel`` counts frames by hand, and the same warning is reached
through different call paths (``simulate`` -> ``prepare`` or ``prepare`` directly, a scenario
built in the CLI or by the user), so hand-counted levels pointed inside flatfree on some of
them. (Python 3.12's ``skip_file_prefixes`` does this; the project supports 3.11.)
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from collections.abc import Iterator

__all__ = ["warn", "recording"]

_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn(message: str, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn(message, category)`` attributed to the first caller outside flatfree."""
    level = 1  # this function's frame
    frame = sys._getframe(0)
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)


@contextlib.contextmanager
def recording() -> Iterator[list[warnings.WarningMessage]]:
    """Every warning of the block recorded in the list it yields, none shown (a repeated one
    too: the filter "always"); the list holds those before an exception as well."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield caught
