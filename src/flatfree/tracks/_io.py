"""Reading track and recording files: bundled names or user paths, strict validation.

Three formats are recognised from the header (a first line that starts with ``#``, or a first
line that is not numeric):

- TUMFTM racetrack-database: ``x_m, y_m, w_tr_right_m, w_tr_left_m`` (a headerless file with
  four columns is read in this order too);
- plain ``x, y`` (a headerless file with two columns, e.g. the LVMS bound files);
- the recording format of ``data/recordings`` (``time(s), x(m), y(m), vx(m/s), ...``).

A header may write a column's unit after its name, in parentheses or brackets (``x(m)``,
``x [m]``; TUMFTM's ``x_m`` suffix too). Values are never converted: a column the loaders read
must be in its unit of :data:`UNITS` (SI: m for x, y and the widths; the recording's columns as
documented in data/recordings/PROVENANCE.md), and any other unit (``x(km)``, ``y [ft]``) is an
error. Columns no loader reads keep whatever unit their header gives.

Every defect raises ``ValueError`` naming the file and the line number (1-based, as an editor
shows it); no row is ever skipped except blank lines and ``#`` comment lines.

References
----------
[TUM-db] TUMFTM racetrack-database, commit e59595d (data/tracks/PROVENANCE.md).
[rec] linklab-uva/deep-dynamics, LVMS_23_01_04_B.csv (data/recordings/PROVENANCE.md).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from flatfree._names import bundled_name as _bundled_name
from flatfree._names import looks_like_path

__all__ = [
    "MIN_POINTS",
    "MIN_SEGMENT_M",
    "UNITS",
    "RawData",
    "bundled_name",
    "read_csv",
    "track_names",
    "raceline_names",
    "recording_names",
    "resolve",
    "validate_polyline",
]

#: A path needs at least this many points (a cubic needs 4 to be determined).
MIN_POINTS = 4
#: Consecutive points closer than this are a zero-length segment [m]. Chosen far below any
#: survey or GPS resolution (1 micrometre), so it only catches defects, never real data.
MIN_SEGMENT_M = 1e-6

_DATA = resources.files("flatfree") / "data"
_TRACKS = _DATA / "tracks"
_RACELINES = _TRACKS / "racelines"
_RECORDINGS = _DATA / "recordings"

#: The LVMS oval has no TUMFTM file: its centerline is built from the recording's bound files.
LVMS_NAME = "LVMS"
LVMS_BOUNDS = ("lvms_inner_bound.csv", "lvms_outer_bound.csv")

# Canonical column names (units stripped) of the recording format [rec].
RECORDING_COLUMNS = (
    "time", "x", "y", "vx", "vy", "phi", "delta", "omega", "ax", "deltadelta",
    "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr", "roll", "throttle_ped_cmd", "brake_ped_cmd",
)
RECORDING_REQUIRED = ("time", "x", "y", "vx", "phi", "delta")
TUM_COLUMNS = ("x", "y", "w_tr_right", "w_tr_left")
#: The unit(s) a header may give each column the loaders read, as written in the files: the SI
#: unit, except the recording's wheel speeds (km/h, filed as ``kmph``) and pedal commands (%,
#: kPa), which :class:`~flatfree.tracks.recording.Recording` keeps as filed [rec]. No conversion.
UNITS = {
    **dict.fromkeys(TUM_COLUMNS, ("m",)),
    "time": ("s",), "vx": ("m/s",), "vy": ("m/s",), "phi": ("rad",), "delta": ("rad",),
    "omega": ("rad/s",), "ax": ("m/s^2", "m/s2", "m/s²"), "deltadelta": ("rad/s",),
    **dict.fromkeys(("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"), ("kmph", "km/h")),
    "roll": ("rad",), "throttle_ped_cmd": ("%",), "brake_ped_cmd": ("kPa",),
}


def _csv_names(folder) -> list[str]:
    return sorted(p.name[:-4] for p in folder.iterdir() if p.name.endswith(".csv"))


def track_names() -> list[str]:
    """Names of the bundled tracks (TUMFTM centerlines, and ``"LVMS"`` from its bounds)."""
    return sorted([*_csv_names(_TRACKS), LVMS_NAME])


def raceline_names() -> list[str]:
    """Names of the bundled race lines (``load_track(name, raceline=True)``)."""
    return _csv_names(_RACELINES)


def recording_names() -> list[str]:
    """Names of the bundled recordings."""
    return [n for n in _csv_names(_RECORDINGS) if not n.startswith("lvms_")]


#: The kinds of bundled CSV data: the folder and the names of each.
_FOLDERS = {"track": _TRACKS, "raceline": _RACELINES, "recording": _RECORDINGS}
_NAMES = {"track": track_names, "raceline": raceline_names, "recording": recording_names}
#: The name lists :func:`bundled_name` looks in: a track may also be a recording's name (its
#: driven path), listed before the tracks' own names, which win.
_LOOKUP = {"track": (recording_names, track_names), "raceline": (raceline_names,),
           "recording": (recording_names,)}


def bundled_name(name: Any, kind: str = "track") -> str | None:
    """The bundled ``kind`` (``"track"``, ``"raceline"`` or ``"recording"``) that ``name``
    names, in its own spelling (``"monza"``, ``" Monza.csv"`` -> ``"Monza"``), else None.

    The one name lookup of the loaders (:func:`resolve`; :mod:`flatfree._names`, shared with
    the vehicles'): case-insensitive, surrounding blanks and a ``.csv`` suffix ignored; a
    ``"track"`` may also be a recording's name (its driven path). It looks at names only: a
    loader reads a value naming an existing file as that file first. Anything but a ``str`` or
    ``os.PathLike`` is no name (None).
    """
    if kind not in _FOLDERS:
        raise ValueError(f"kind = {kind!r}: must be one of {', '.join(_FOLDERS)}")
    return _bundled_name(name, _LOOKUP[kind], ".csv")


def resolve(name_or_path: str | Path, kind: str) -> tuple[Any, str]:
    """Return ``(file, display_name)`` for a bundled name (case-insensitive) or a path.

    ``kind`` is ``"track"``, ``"raceline"`` or ``"recording"``. A string that names an existing
    file is read as a path; a bundled name (:func:`bundled_name`) wins otherwise. ``"LVMS"``
    returns ``(None, "LVMS")`` (built from the bound files by the caller). Race lines are bundled
    only: for a ``"raceline"``, a file or a path is an error.
    """
    return resolve_named(name_or_path, kind)[:2]


def resolve_named(name_or_path: str | Path, kind: str) -> tuple[Any, str, str | None]:
    """:func:`resolve`'s ``(file, display_name)`` and the bundled name it resolved (its own
    spelling; None for a file): the one place of the rule "a file first, then a name"."""
    p = Path(name_or_path)
    if p.is_file():
        if kind == "raceline":
            raise _not_bundled(name_or_path)
        return p, str(p), None
    name = bundled_name(name_or_path, kind)
    if name is not None:
        return (*bundled_file(name, kind), name)
    key = str(name_or_path).strip()
    if looks_like_path(key):
        if kind == "raceline":
            raise _not_bundled(name_or_path)
        raise ValueError(f"{kind} file not found: {str(name_or_path)!r}")
    names = _NAMES[kind]()
    extra = f"; or a recording: {', '.join(recording_names())}" if kind == "track" else ""
    path = "" if kind == "raceline" else "; or give the path of a CSV file"
    raise ValueError(
        f"unknown {kind} {str(name_or_path)!r}; bundled names: {', '.join(names)}{extra}{path}"
    )


def bundled_file(name: str, kind: str) -> tuple[Any, str]:
    """``(file, display_name)`` of the bundled ``name`` as :func:`bundled_name` spells it, a
    file of the current folder of that name notwithstanding (:func:`resolve` looks for that)."""
    if kind == "track" and name == LVMS_NAME:
        return None, LVMS_NAME
    own = name in _NAMES[kind]()  # else a recording's name given as a track
    folder = _FOLDERS[kind] if own else _RECORDINGS
    return folder / f"{name}.csv", f"{name}.csv"


def _not_bundled(name_or_path) -> ValueError:
    """The error for a file given as a race line: there are bundled race lines only."""
    return ValueError(
        f"{str(name_or_path)!r}: race lines are bundled only (for "
        f"{', '.join(raceline_names())}); read a file of your own as a track, without "
        "raceline=True"
    )


def bundled_recording_file(name: str):
    """A file in the bundled recordings folder (bound files)."""
    return _RECORDINGS / name


@dataclass(frozen=True, slots=True)
class RawData:
    """The parsed numeric content of a CSV file.

    Attributes
    ----------
    source : str
        File name used in messages.
    columns : tuple of str
        Canonical column names (units stripped, lower case), e.g. ``("x", "y")``.
    values : ndarray, shape (n, len(columns))
        The numbers, all finite.
    lines : ndarray of int, shape (n,)
        1-based line number of every row, for messages.
    fmt : str
        ``"tum"``, ``"xy"`` or ``"recording"``.
    """

    source: str
    columns: tuple[str, ...]
    values: np.ndarray
    lines: np.ndarray
    fmt: str

    def col(self, name: str) -> np.ndarray:
        """One column by canonical name."""
        return self.values[:, self.columns.index(name)]

    def where(self, i: int) -> str:
        """``"<file>, line <n>"`` for row ``i``."""
        return f"{self.source}, line {int(self.lines[i])}"

    def line(self, i: int) -> str:
        """``"line <n>"`` for row ``i``."""
        return f"line {int(self.lines[i])}"


#: A unit after a column name: ``time(s)``, ``x [m]``.
_UNIT = re.compile(r"\s*(?:\((?P<paren>[^()]*)\)|\[(?P<bracket>[^\[\]]*)\])\s*$")


def _name_and_unit(cell: str) -> tuple[str, str | None]:
    """``'x_m'`` -> ``('x', None)``, ``'time(s)'`` -> ``('time', 's')``, ``'x [m]'`` ->
    ``('x', 'm')``, ``'w_tr_right_m'`` -> ``('w_tr_right', None)``: the canonical (lower case)
    name and the unit written in parentheses or brackets (blanks removed), if any."""
    n = cell.strip()
    unit = None
    m = _UNIT.search(n)
    if m is not None:
        unit = "".join((m["paren"] if m["paren"] is not None else m["bracket"]).split())
        n = n[: m.start()]
    n = n.lower()
    if n.endswith("_m") and n not in ("_m",):
        n = n[:-2]
    return n, unit


def _canonical(cell: str) -> str:
    """The canonical column name of a header cell (:func:`_name_and_unit`)."""
    return _name_and_unit(cell)[0]


def _check_units(cells: tuple[str, ...], source: str, line: int) -> None:
    """Refuse a unit in the header that is not the column's unit of :data:`UNITS`."""
    for cell in cells:
        name, unit = _name_and_unit(cell)
        if unit is not None and name in UNITS and unit not in UNITS[name]:
            want = " or ".join(repr(u) for u in UNITS[name])
            raise ValueError(
                f"{source}, line {line}, column {name!r}: unit {unit!r} is not accepted; the "
                f"values must be in {want} (header {cell.strip()!r}; units are not converted)"
            )


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _detect_format(columns: tuple[str, ...] | None, ncol: int, source: str, line: int):
    """Return (fmt, canonical columns)."""
    if columns is None:
        if ncol == 2:
            return "xy", ("x", "y")
        if ncol == 4:
            return "tum", TUM_COLUMNS
        raise ValueError(
            f"{source}, line {line}: {ncol} columns and no header; cannot tell the format "
            "(expected 2 columns x,y or 4 columns x_m,y_m,w_tr_right_m,w_tr_left_m, or a header)"
        )
    cols = columns
    if "time" in cols:
        missing = [c for c in RECORDING_REQUIRED if c not in cols]
        if missing:
            raise ValueError(f"{source}, line {line}: recording header lacks column(s) {missing}")
        return "recording", cols
    if any(c.startswith("w_tr") for c in cols):
        missing = [c for c in TUM_COLUMNS if c not in cols]
        if missing:
            raise ValueError(
                f"{source}, line {line}: missing column(s) {[m + '_m' for m in missing]} "
                "(the TUMFTM format needs x_m, y_m, w_tr_right_m, w_tr_left_m)"
            )
        return "tum", cols
    missing = [c for c in ("x", "y") if c not in cols]
    if missing:
        raise ValueError(
            f"{source}, line {line}: missing column(s) {missing} in header {list(columns)}"
        )
    return "xy", cols


def read_csv(file, source: str) -> RawData:
    """Parse a track, bound or recording CSV strictly.

    Parameters
    ----------
    file : path or importlib Traversable
    source : str
        Display name for messages.

    Raises
    ------
    ValueError
        Missing file, unknown layout, missing columns, a row with the wrong number of cells,
        a non-numeric cell, NaN or infinity; the message gives the file and line number.
    """
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{source}: file not found") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{source}: not a UTF-8 text file ({exc})") from None
    except OSError as exc:  # a folder, no permission, ...
        raise ValueError(f"{source}: cannot read it ({exc.strerror or exc})") from None

    header: tuple[str, ...] | None = None  # the header's cells, as written
    header_line = 0
    comments: list[tuple[int, tuple[str, ...]]] = []  # comment lines before the first data row
    rows: list[list[str]] = []
    lines: list[int] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if header is None and not rows:
                body = line.lstrip("#").strip()
                if body:
                    comments.append((lineno, tuple(body.split(","))))
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None and not rows and not all(_is_number(c) for c in cells):
            header = tuple(cells)  # a plain (uncommented) header line
            header_line = lineno
            continue
        rows.append(cells)
        lines.append(lineno)
    if not rows:
        raise ValueError(f"{source}: no data rows")
    if header is None and comments:
        # a commented header (TUMFTM, recordings): the last comment line before the data with
        # as many comma-separated names as the first data row has cells, or naming x and y;
        # free text is skipped
        for ln, cells in reversed(comments):
            if len(cells) == len(rows[0]) or {"x", "y"} <= {_canonical(c) for c in cells}:
                header, header_line = cells, ln
                break
    ncol = len(header) if header is not None else len(rows[0])
    if header is not None:
        _check_units(header, source, header_line)
    names = None if header is None else tuple(_canonical(c) for c in header)
    fmt, columns = _detect_format(names, ncol, source, header_line or lines[0])
    for cells, ln in zip(rows, lines, strict=True):
        if len(cells) != ncol:
            raise ValueError(
                f"{source}, line {ln}: expected {ncol} values ({', '.join(columns)}), "
                f"found {len(cells)}"
            )
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        for cells, ln in zip(rows, lines, strict=True):
            for j, c in enumerate(cells):
                if not _is_number(c):
                    raise ValueError(
                        f"{source}, line {ln}, column {columns[j]!r}: {c!r} is not a number"
                    ) from None
        raise  # pragma: no cover - numpy and float() disagree
    bad = ~np.isfinite(values)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ValueError(
            f"{source}, line {lines[i]}, column {columns[j]!r}: {rows[i][j]!r} is not finite "
            "(NaN and infinity are not allowed)"
        )
    return RawData(source, columns, values, np.asarray(lines, dtype=np.int64), fmt)


def validate_polyline(
    x: np.ndarray, y: np.ndarray, where, source: str, *, short=None, allow_closure: bool = True
) -> bool:
    """Check a point sequence; return True when the last point repeats the first.

    ``where(i)`` formats the location of point ``i`` (file and line, or array index), ``short(i)``
    a short form of it for a second location in the same message (default ``where``).
    Errors: fewer than :data:`MIN_POINTS` points, a point that repeats the previous one, a
    zero-length segment (shorter than :data:`MIN_SEGMENT_M`). A last point equal to the first
    is the explicit closure of a loop (the LVMS bound files use it): it is reported by the
    return value, and the caller drops it and treats the path as closed.
    """
    short = short or where
    n = len(x)
    closure = (
        allow_closure and n > MIN_POINTS and math.hypot(x[-1] - x[0], y[-1] - y[0]) < MIN_SEGMENT_M
    )
    m = n - 1 if closure else n
    if m < MIN_POINTS:
        raise ValueError(
            f"{source}: {m} point(s){' (after the closing repeat of the first)' if closure else ''}"
            f"; a path needs at least {MIN_POINTS}"
            + (f" (last at {short(n - 1)})" if n else "")
        )
    dx = np.diff(x[:m])
    dy = np.diff(y[:m])
    same = (dx == 0.0) & (dy == 0.0)
    if same.any():
        i = int(np.flatnonzero(same)[0])
        raise ValueError(
            f"{where(i + 1)}: repeated point ({float(x[i + 1])!r}, {float(y[i + 1])!r}) "
            f"equals the previous point ({short(i)})"
        )
    seg = np.hypot(dx, dy)
    tiny = seg < MIN_SEGMENT_M
    if tiny.any():
        i = int(np.flatnonzero(tiny)[0])
        raise ValueError(
            f"{where(i + 1)}: zero-length segment from the previous point ({short(i)}): "
            f"length {seg[i]:.3g} m < {MIN_SEGMENT_M:g} m"
        )
    return bool(closure)
