"""The one bundled-name lookup of the loaders (tracks, race lines, recordings, vehicles, tyres),
and the one rule by which a file's relative references are read from its folder (:func:`anchored`).

A name matches a bundled file's name case-insensitively, surrounding blanks ignored, and with
the kind's own file suffix optional when the kind allows it (a track's ``.csv``; not a vehicle's
``.toml``, which its loader reads as a path).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import PurePath
from typing import Any

__all__ = ["bundled_name", "looks_like_path", "anchored"]


@functools.cache
def _by_lower(*names: Callable[[], list[str]]) -> dict[str, str]:
    """{lower-case name: name} of the names the functions ``names`` list (a bundled folder,
    fixed while the program runs: one cache per folder); a later list's name wins."""
    by_lower: dict[str, str] = {}
    for listing in names:
        by_lower.update({n.lower(): n for n in listing()})
    return by_lower


def bundled_name(name: Any, names: tuple[Callable[[], list[str]], ...],
                 suffix: str | None = None) -> str | None:
    """The bundled name, in its own spelling, that ``name`` names among those the functions
    ``names`` list (a later one's wins), else None: case-insensitive, surrounding blanks
    ignored, a trailing ``suffix`` (e.g. ``".csv"``, lower case) too. Anything but a ``str`` or
    ``os.PathLike`` is no name (None)."""
    if not isinstance(name, (str, os.PathLike)):
        return None
    key = os.fspath(name)
    if not isinstance(key, str):  # a bytes path names no bundled file
        return None
    key = key.strip().lower()
    if suffix is not None:
        key = key.removesuffix(suffix)
    return _by_lower(*names).get(key)


def looks_like_path(text: str) -> bool:
    """True for a value the loaders read as a file path even where no such file exists (their
    error is then "file not found", not "unknown name"): one with a folder separator or a file
    suffix. No bundled name has either."""
    return "/" in text or "\\" in text or bool(PurePath(text).suffix)


def anchored(value: Any, folder: str | os.PathLike[str], bundled: Callable[[str], str | None]
             ) -> Any:
    """``value``, a bundled name or a file path written in a file of ``folder``, as the loaders
    read it: an existing file there as its absolute path, else a bundled name (``bundled``,
    the kind's lookup) in its own spelling, else a value that looks like a path
    (:func:`looks_like_path`) absolute in ``folder``, else (and what is no name or path) as
    given. A scenario file's references and a vehicle file's tyres follow this one rule."""
    if not isinstance(value, (str, os.PathLike)):
        return value
    text = os.fspath(value)
    if os.path.isabs(text):
        return text
    full = os.path.normpath(os.path.join(os.path.abspath(folder), text))
    if os.path.isfile(full):
        return full
    name = bundled(text)
    if name is not None:
        return name
    if looks_like_path(text):
        return full
    return text  # neither a file nor a name: the loader's error names it as written
