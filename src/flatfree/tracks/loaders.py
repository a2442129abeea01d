"""Loading tracks: bundled names or user files, TUMFTM, plain x,y, recordings, LVMS bounds.

References
----------
[TUM-db] TUMFTM racetrack-database (data/tracks/PROVENANCE.md).
[rec] deep-dynamics LVMS recording and bounds (data/recordings/PROVENANCE.md).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import BPoly

from flatfree._validate import positive
from flatfree._warn import recording, warn
from flatfree.tracks import _io
from flatfree.tracks.geometry import DEFAULT_DS, DEFAULT_SMOOTHING_LENGTH, Track, _as_1d

__all__ = ["TrackPoints", "read_track_points", "load_track", "lvms_centerline",
           "bridge_closure"]


@dataclass(frozen=True, slots=True, eq=False)
class TrackPoints:
    """Raw points of a track file, as read (no smoothing, no resampling).

    Attributes
    ----------
    name, source : str
    x, y : ndarray
        Points [m].
    w_left, w_right : ndarray
        Distances to the left / right edge [m] (NaN when the file has none).
    closed : bool or None
        True when the file marks the loop by repeating its first point (that repeat is removed
        from ``x, y``); None when the file does not say (``Track.from_points`` then decides).
    """

    name: str
    source: str
    x: np.ndarray
    y: np.ndarray
    w_left: np.ndarray
    w_right: np.ndarray
    closed: bool | None

    def to_track(self, *, closed: bool | None = None, ds: float = DEFAULT_DS,
                 smoothing_length: float | None = None, name: str | None = None) -> Track:
        """The points smoothed and resampled (:meth:`Track.from_points`), with this file's
        ``closed`` flag and name unless given, and the smoothing default of :func:`load_track`
        (``LVMS_SMOOTHING_LENGTH`` for the LVMS midline, else ``DEFAULT_SMOOTHING_LENGTH``)."""
        if smoothing_length is None:
            smoothing_length = (LVMS_SMOOTHING_LENGTH if self.name == _io.LVMS_NAME
                                else DEFAULT_SMOOTHING_LENGTH)
        return Track.from_points(self.x, self.y, w_left=self.w_left, w_right=self.w_right,
                                 closed=self.closed if closed is None else closed, ds=ds,
                                 smoothing_length=smoothing_length,
                                 name=self.name if name is None else name, source=self.source)

    def polyline_length(self, closed: bool) -> float:
        """Length of the raw polyline [m], with the closing segment when ``closed``."""
        x = np.append(self.x, self.x[0]) if closed else self.x
        y = np.append(self.y, self.y[0]) if closed else self.y
        return float(np.hypot(np.diff(x), np.diff(y)).sum())


def _points_from_raw(raw: _io.RawData, name: str) -> TrackPoints:
    x = raw.col("x")
    y = raw.col("y")
    if raw.fmt == "tum":
        wr = raw.col("w_tr_right")
        wl = raw.col("w_tr_left")
        for arr, col in ((wr, "w_tr_right_m"), (wl, "w_tr_left_m")):
            if (arr < 0).any():
                i = int(np.flatnonzero(arr < 0)[0])
                raise ValueError(
                    f"{raw.where(i)}, column {col!r}: width {float(arr[i])!r} m must be >= 0"
                )
    else:
        wr = np.full_like(x, np.nan)
        wl = np.full_like(x, np.nan)
    closure = _io.validate_polyline(x, y, raw.where, raw.source, short=raw.line)
    if closure:
        x, y, wl, wr = x[:-1], y[:-1], wl[:-1], wr[:-1]
    return TrackPoints(name, raw.source, x, y, wl, wr, True if closure else None)


#: Smoothing cut-off wavelength for the LVMS centerline built from the bound files [m]. The
#: bound files are generated (PROVENANCE.md: a constant 15.0 m width) and their midline carries
#: short wiggles that the default 20 m cut-off turns into curvature down to -0.0040 1/m on an
#: oval without a right-hand bend, and up to 0.0119 1/m in its turns (-0.0014 / 0.0062 at 60 m;
#: benchmarks/lvms_seam.py); the oval's turns have radii >= 150 m (1st/99th
#: percentile of the recorded path's curvature: -0.0009 / +0.0065 1/m, PROVENANCE.md), which a
#: 60 m cut-off passes unchanged (gain 1 - (60 / (2 pi 150))^8 ~ 1).
LVMS_SMOOTHING_LENGTH = 60.0

#: The stretch of the LVMS bound files' loop closure that :func:`lvms_centerline` replaces:
#: from this far before the first point to this far after it [m]. Both generated bound files
#: start at the same place and carry the same artefact there: the line bulges sideways in the
#: ~40 m after its first point, by up to 0.67 / 0.71 m (the bridge's largest move, 20 m after
#: it; at most 4 cm before it), which the recorded car does not drive (its distance from the
#: smoothed midline dipped by the bulge's shape on both of its passes: a span of 48 / 43 cm over
#: the 100 m around the first point, 8 / 19 cm with the bridge, its own wander). Left in, it was
#: an S-bend at the start line, curvature -0.0016 1/m 19 m after it and +0.0014 at 50 m
#: (bridged: -0.0002 / +0.0005, turn 1's entry), where the car starts at 45 m/s into a 6 m/s^2
#: braking: the friction-only profile's lateral acceleration in the first 70 m went -3.6 /
#: +2.7 m/s^2 (bridged: -0.4 / +2.3), a slalom that no real lap has. Measured by
#: benchmarks/lvms_seam.py.
LVMS_SEAM_M = (40.0, 50.0)


def bridge_closure(x: np.ndarray, y: np.ndarray, before: float, after: float, *,
                   fit: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Replace the points of a closed polyline near its first point by a smooth bridge [m].

    The points less than ``before`` [m] of arc length before the first point (the end of the
    arrays) and less than ``after`` [m] after it are moved sideways, in the frame of the chord
    between the two ends of that stretch, onto the quintic that matches the line on either
    side in position, slope and second derivative (C2): each side's values come from a
    least-squares parabola through the points within ``fit`` [m] beyond the stretch's end.
    Points keep their place along the chord (so their spacing changes by a fraction of the
    move), every other point is untouched. For a stretch that is nearly straight in the chord's
    frame (slopes well below 1), as a seam artefact on a straight is.

    Returns new ``x, y`` arrays.

    Raises
    ------
    ValueError
        Coordinates that are not 1-D real arrays of one length, a length that is not positive, or
        a stretch (with its two fits) that is not shorter than half the loop.
    """
    x = _as_1d("x", x)
    y = _as_1d("y", y, x.size)
    before, after, fit = (positive(k, v, "m") for k, v in
                          (("before", before), ("after", after), ("fit", fit)))
    seg = np.hypot(np.diff(x, append=x[0]), np.diff(y, append=y[0]))
    length = float(seg.sum())
    s = np.concatenate([[0.0], np.cumsum(seg[:-1])])
    s = np.where(s > 0.5 * length, s - length, s)  # signed arc length from the first point
    reach = before + after + 2.0 * fit
    if not reach < 0.5 * length:
        raise ValueError(f"before + after + 2 fit = {reach:g} m: the stretch and its fits must "
                         f"be shorter than half the loop ({length:g} m)")
    a = int(np.argmin(np.abs(s + before)))
    b = int(np.argmin(np.abs(s - after)))
    ex, ey = x[b] - x[a], y[b] - y[a]
    chord = math.hypot(ex, ey)
    ex, ey = ex / chord, ey / chord
    u = (x - x[a]) * ex + (y - y[a]) * ey  # along the chord
    v = -(x - x[a]) * ey + (y - y[a]) * ex  # across it (left positive)

    def side(lo: float, hi: float, at: float) -> list[float]:
        m = (s >= lo) & (s <= hi)
        c = np.polyfit(u[m], v[m], 2)
        return [float(np.polyval(c, at)), float(np.polyval(np.polyder(c), at)), 2.0 * c[0]]

    ua, ub = float(u[a]), float(u[b])
    # the quintic from its value, slope and second derivative at both ends
    quintic = BPoly.from_derivatives([ua, ub], [side(-before - fit, -before, ua),
                                                side(after, after + fit, ub)])
    inside = (s > -before) & (s < after)
    move = quintic(u[inside]) - v[inside]
    xn, yn = x.copy(), y.copy()
    xn[inside] -= move * ey
    yn[inside] += move * ex
    return xn, yn


def lvms_centerline(*, bridge_seam: bool = True) -> TrackPoints:
    """Centerline of the LVMS oval from the bundled bound files [rec].

    For each point of the inner bound, the foot point on the outer bound (nearest vertex, then
    the nearest of its two adjacent segments) gives the local width; the centerline point is
    the midpoint, and each side gets half the width. Orientation: counter-clockwise, the
    direction the recording drives (PROVENANCE.md), so the inner bound is on the left. The
    bound files' loop-closure artefact is bridged (:data:`LVMS_SEAM_M`, :func:`bridge_closure`);
    ``bridge_seam=False`` keeps it (the files' own midline: a rough path with an S-bend at the
    start line, which tests and benchmarks of rough paths use).
    """
    pts = []
    for fname in _io.LVMS_BOUNDS:
        raw = _io.read_csv(_io.bundled_recording_file(fname), fname)
        x, y = raw.col("x"), raw.col("y")
        if _io.validate_polyline(x, y, raw.where, raw.source, short=raw.line):
            x, y = x[:-1], y[:-1]
        pts.append(np.column_stack([x, y]))
    inner, outer = pts
    from scipy.spatial import cKDTree  # late: only the LVMS centerline needs it

    tree = cKDTree(outer)
    _, k = tree.query(inner)
    n = outer.shape[0]
    best = np.full(inner.shape[0], np.inf)
    foot = np.empty_like(inner)
    for a_off, b_off in ((-1, 0), (0, 1)):  # the two segments adjacent to the nearest vertex
        a = outer[(k + a_off) % n]
        b = outer[(k + b_off) % n]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", inner - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
        p = a + t[:, None] * ab
        d = np.hypot(*(inner - p).T)
        better = d < best
        best[better] = d[better]
        foot[better] = p[better]
    centre = 0.5 * (inner + foot)
    half = 0.5 * best
    area = 0.5 * np.sum(centre[:, 0] * np.roll(centre[:, 1], -1)
                        - np.roll(centre[:, 0], -1) * centre[:, 1])
    if area < 0:  # make it counter-clockwise
        centre, half = centre[::-1], half[::-1]
    x, y = centre[:, 0].copy(), centre[:, 1].copy()
    how = "midline"
    if bridge_seam:
        # the generated bounds' closure artefact (LVMS_SEAM_M: before and after the first point
        # in the driving direction; the seam lies between the last point and the first)
        x, y = bridge_closure(x, y, *LVMS_SEAM_M)
        how += (f", closure artefact bridged over {LVMS_SEAM_M[0]:g} m before and "
                f"{LVMS_SEAM_M[1]:g} m after the first point")
    src = f"{_io.LVMS_BOUNDS[0]} + {_io.LVMS_BOUNDS[1]} ({how})"
    return TrackPoints(_io.LVMS_NAME, src, x, y, half.copy(), half.copy(), True)


def read_track_points(name_or_path: str | Path, *, raceline: bool = False) -> TrackPoints:
    """Read the raw points of a bundled track (name, case-insensitive) or of a CSV file.

    Parameters
    ----------
    name_or_path : str or Path
        ``"Monza"``, ``"spa"``, ``"LVMS"``, a recording name (its driven path, see
        :func:`load_track`), or the path of a TUMFTM, x,y or recording CSV file.
    raceline : bool
        Read the bundled race line instead of the centerline (bundled tracks only: a file, or a
        name without a race line, is an error).

    Raises
    ------
    ValueError
        Unknown name, missing file, or a defective file (message with file and line).
    """
    file, display, name = _io.resolve_named(name_or_path, "raceline" if raceline else "track")
    return _points_of(file, display, bundled=name is not None)


def _points_of(file, display: str, bundled: bool) -> TrackPoints:
    """:func:`read_track_points` of a resolved ``(file, display)`` (:func:`_io.resolve`)."""
    if file is None:
        return lvms_centerline()
    raw = _io.read_csv(file, display)
    name = Path(display).stem
    if raw.fmt == "recording":
        from flatfree.tracks.recording import Recording

        return Recording.from_raw(raw, name, bundled=bundled).track_points()
    return _points_from_raw(raw, name)


def load_track(
    name_or_path: str | Path,
    *,
    raceline: bool = False,
    closed: bool | None = None,
    ds: float = DEFAULT_DS,
    smoothing_length: float | None = None,
) -> Track:
    """Load a bundled track by name, or a user's track file, as a resampled :class:`Track`.

    Parameters
    ----------
    name_or_path : str or Path
        A bundled name (case-insensitive): Budapest, Catalunya, IMS, Monza, Norisring, Spa
        (TUMFTM centerlines with widths [TUM-db]), ``"LVMS"`` (the oval of the recording, its
        centerline built from the bound files), or a recording name such as
        ``"LVMS_23_01_04_B"`` (the path driven on track, an open path); or a path to a CSV in
        the TUMFTM format (x_m, y_m, w_tr_right_m, w_tr_left_m), plain x,y, or the recording
        format. A user's file goes through exactly the same steps as a bundled one.
    raceline : bool
        Load the TUMFTM minimum-curvature race line (no widths) instead of the centerline; there
        are bundled race lines only (``raceline_names()``): a file is an error (load a race
        line of your own as a track).
    closed : bool, optional
        Loop or open path; ``None`` (default) detects it (:meth:`Track.from_points`: a file's
        closing repeat of its first point, or an end within 3 point spacings of the start,
        with a ``UserWarning`` when that gap exceeds 1.5 spacings); ``False`` keeps an open
        road whose ends lie close open.
    ds : float
        Resampling step [m] (see :meth:`Track.from_points`).
    smoothing_length : float, optional
        Smoothing cut-off wavelength [m] (see :meth:`Track.from_points`); default
        ``DEFAULT_SMOOTHING_LENGTH`` (20 m), and ``LVMS_SMOOTHING_LENGTH`` (60 m) for the LVMS
        centerline built from the generated bound files.

    Returns
    -------
    Track
        A bundled track is built once per process for a set of arguments and shared by every
        caller (a Track is immutable); a file is read on every call.

    Notes
    -----
    The bundled centerlines derive from OpenStreetMap data: credit "(c) OpenStreetMap
    contributors" (data/tracks/PROVENANCE.md). Licenses: LGPL-3.0 (tracks), GPL-3.0 (recording).
    """
    # a file is read as the file, a bundled name is built once (module docstring)
    file, display, name = _io.resolve_named(name_or_path, "raceline" if raceline else "track")
    if name is not None:
        args = (name, raceline, closed, ds, smoothing_length)
        try:
            hash(args)
        except TypeError:  # an unhashable argument: the builder's to refuse, naming it
            return _build_track(_points_of(file, display, bundled=True), *args[1:])
        track, said = _bundled_track(*args)
        for message, category in said:  # what its build said, said on every call
            warn(message, category)
        return track
    return _build_track(_points_of(file, display, bundled=False), raceline, closed, ds,
                        smoothing_length)


def _build_track(pts: TrackPoints, raceline, closed, ds, smoothing_length) -> Track:
    return pts.to_track(closed=closed, ds=ds, smoothing_length=smoothing_length,
                        name=f"{pts.name} raceline" if raceline else None)


@functools.lru_cache(maxsize=16, typed=True)
def _bundled_track(name: str, raceline: bool, closed, ds, smoothing_length):
    """A bundled track, built once per process for each set of arguments (typed: an argument
    equal to another of another type, np.float32(0.5) and 0.5, is built, and so checked, on
    its own), with the warnings its build gave: ``(track, ((message, category), ...))``. The
    16 latest are kept (a Spa geometry is 0.56 MB at the default ds, 20x that at ds =
    0.05 m). The package's files do not change under a running process, and a Track is
    immutable (frozen, its geometry a read-only view that cannot be made writeable), so every
    caller may share it. Building one (reading, smoothing, the spline, the resampling) is most
    of a process's first ``prepare`` (benchmarks/profile_closed_loop.py part 4 prints both)."""
    with recording() as caught:
        # the bundled file of that name, not a file of the current folder spelled like it
        pts = _points_of(*_io.bundled_file(name, "raceline" if raceline else "track"),
                         bundled=True)
        track = _build_track(pts, raceline, closed, ds, smoothing_length)
    return track, tuple((str(w.message), w.category) for w in caught)
