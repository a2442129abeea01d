"""Recorded driving as a reference: the LVMS recording of the Dallara AV-21 (or a user's file).

The recording format (data/recordings/PROVENANCE.md) has, at 25 Hz: UNIX time, x, y [m],
body velocities vx, vy [m/s], yaw phi [rad] (counter-clockwise from +x), the front road-wheel
steer angle delta [rad], yaw rate omega [rad/s], longitudinal acceleration ax [m/s^2], and more.
The recorded steer is kept so that a controller's steer can be compared with the driver's
(the paper's Figure 6).

Smoothing (PROVENANCE.md: "the XY-derived speed has 25 Hz position jitter ... smooth it before
differentiating"): x, y and vx are smoothed with a zero-phase Savitzky-Golay filter, cubic, over
a window of ``window`` seconds (default 1 s = 25 samples); derivatives come from the same filter.

References
----------
[rec] J. Chrosniak, J. Ning, M. Behl, "Deep Dynamics: Vehicle Dynamics Modeling With a
    Physics-Constrained Neural Network for Autonomous Racing", IEEE RA-L 9(6), 2024,
    doi:10.1109/LRA.2024.3388847; data from linklab-uva/deep-dynamics (GPL-3.0).
[SG] A. Savitzky, M. J. E. Golay, Anal. Chem. 36(8), 1964 (scipy.signal.savgol_filter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
from scipy.interpolate import CubicSpline

from flatfree._validate import positive
from flatfree.tracks import _io
from flatfree.tracks.geometry import DEFAULT_DS, DEFAULT_SMOOTHING_LENGTH, Track, path_eval_many
from flatfree.tracks.reference import N_RS, RS, Reference

__all__ = ["Recording", "load_recording"]

#: Default smoothing window [s] of the Savitzky-Golay filter (25 samples at 25 Hz): long enough
#: to remove the 25 Hz position jitter, short against the ~10 s corners of the oval.
DEFAULT_WINDOW_S = 1.0
#: A sample "moves" above this speed [m/s] (PROVENANCE.md uses the same threshold).
DEFAULT_V_MIN = 1.0
#: Minimum spacing of the points that define a recording's path [m]: standstill samples would
#: otherwise give zero-length segments.
PATH_POINT_SPACING_M = 0.5


@numba.njit(cache=True)
def _inside(px, py, poly):
    """Even-odd point-in-polygon test for many points (poly: (m, 2), not repeated)."""
    out = np.zeros(px.shape[0], dtype=np.bool_)
    m = poly.shape[0]
    for k in range(px.shape[0]):
        x = px[k]
        y = py[k]
        c = False
        j = m - 1
        for i in range(m):
            yi = poly[i, 1]
            yj = poly[j, 1]
            if (yi > y) != (yj > y):
                xc = poly[i, 0] + (y - yi) * (poly[j, 0] - poly[i, 0]) / (yj - yi)
                if x < xc:
                    c = not c
            j = i
        out[k] = c
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a boolean array."""
    e = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in e.reshape(-1, 2)]


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Recording:
    """A recorded drive, time-indexed (columns by name, SI units; wheel speeds stay km/h as filed,
    names ``wheel_*``).

    Attributes
    ----------
    name, source : str
    t0_epoch : float
        UNIX time of the file's first sample [s].
    data : dict of str -> ndarray
        Columns (canonical names: ``time, x, y, vx, vy, phi, delta, omega, ax, ...``);
        ``time`` is relative to the file's first sample [s].
    bounds : tuple (inner, outer) of ndarray (m, 2), or None
        Track edges (the bundled LVMS recording has them).
    """

    name: str
    source: str = ""
    t0_epoch: float = 0.0
    data: dict = field(repr=False)
    bounds: tuple | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if "time" not in self.data:
            raise ValueError("data: a recording needs a 'time' column")
        n = np.asarray(self.data["time"]).shape[0]
        cols = {}
        for k, v in self.data.items():
            a = np.ascontiguousarray(v, dtype=float)
            if a.shape != (n,):
                raise ValueError(f"data[{k!r}]: all columns must have the same length")
            a.setflags(write=False)
            cols[k] = a
        object.__setattr__(self, "data", cols)

    @classmethod
    def from_raw(cls, raw: _io.RawData, name: str, *, bundled: bool = False) -> Recording:
        """Build from parsed CSV data, checking that time increases strictly.

        ``bundled``: the file is the bundled LVMS recording, whose track bounds are attached.
        """
        t = raw.col("time")
        dt = np.diff(t)
        if (dt <= 0).any():
            i = int(np.flatnonzero(dt <= 0)[0]) + 1
            raise ValueError(
                f"{raw.where(i)}, column 'time': {float(t[i])!r} s does not increase "
                f"(previous {float(t[i - 1])!r} s at line {int(raw.lines[i - 1])})"
            )
        if len(t) < _io.MIN_POINTS:
            raise ValueError(f"{raw.source}: {len(t)} samples; need at least {_io.MIN_POINTS}")
        data = {c: raw.values[:, j] for j, c in enumerate(raw.columns)}
        data["time"] = t - t[0]
        bounds = _lvms_bounds() if bundled and name.lower().startswith("lvms") else None
        return cls(name=name, source=raw.source, t0_epoch=float(t[0]), data=data, bounds=bounds)

    # -- access ------------------------------------------------------------------------------
    def __getitem__(self, name: str) -> np.ndarray:
        if name == "psi":
            return self.psi
        try:
            return self.data[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; available: {', '.join(self.data)}") from None

    def __len__(self) -> int:
        return int(self.data["time"].shape[0])

    @property
    def t(self) -> np.ndarray:
        """Time from the file's first sample [s]."""
        return self.data["time"]

    @property
    def psi(self) -> np.ndarray:
        """Recorded yaw, unwrapped [rad]."""
        return np.unwrap(self.data["phi"])

    @property
    def sample_time(self) -> float:
        """Median sample interval [s]."""
        return float(np.median(np.diff(self.t)))

    def __repr__(self) -> str:
        return (f"Recording(name={self.name!r}, samples={len(self)}, "
                f"t=[{self.t[0]:.2f}, {self.t[-1]:.2f}] s)")

    # -- selection ---------------------------------------------------------------------------
    def select(self, t_start: float | None = None, t_end: float | None = None) -> Recording:
        """Samples with t_start <= t <= t_end [s] (times from the file's first sample)."""
        t = self.t
        lo = -np.inf if t_start is None else float(t_start)
        hi = np.inf if t_end is None else float(t_end)
        m = (t >= lo) & (t <= hi)
        if m.sum() < _io.MIN_POINTS:
            raise ValueError(f"select({t_start!r}, {t_end!r}): fewer than {_io.MIN_POINTS} samples")
        return self._subset(m)

    def _subset(self, m) -> Recording:
        return Recording(name=self.name, source=self.source, t0_epoch=self.t0_epoch,
                         data={k: v[m] for k, v in self.data.items()}, bounds=self.bounds)

    def moving(self, v_min: float = DEFAULT_V_MIN) -> Recording:
        """The longest run of samples with vx > v_min [m/s]."""
        runs = _runs(self.data["vx"] > v_min)
        if not runs:
            raise ValueError(f"{self.name}: never faster than v_min = {v_min} m/s")
        a, b = max(runs, key=lambda r: r[1] - r[0])
        return self._subset(slice(a, b))

    def inside_bounds(self) -> np.ndarray:
        """Boolean per sample: between the inner and outer bound (even-odd test)."""
        if self.bounds is None:
            raise ValueError(f"{self.name}: no track bounds known for this recording")
        inner, outer = self.bounds
        x = np.ascontiguousarray(self.data["x"])
        y = np.ascontiguousarray(self.data["y"])
        return _inside(x, y, outer) & ~_inside(x, y, inner)

    def on_track(self, v_min: float = DEFAULT_V_MIN) -> Recording:
        """The longest run of samples moving (vx > v_min) AND between the track bounds.

        For the LVMS recording this is t = 102.48 ... 429.60 s: the car leaves the pit area at
        ~24 s and is outside the bounds until ~102 s (PROVENANCE.md).
        """
        if self.bounds is None:
            return self.moving(v_min)
        runs = _runs(self.inside_bounds() & (self.data["vx"] > v_min))
        if not runs:
            raise ValueError(f"{self.name}: no moving sample between the bounds")
        a, b = max(runs, key=lambda r: r[1] - r[0])
        return self._subset(slice(a, b))

    # -- smoothing, path, reference ----------------------------------------------------------
    def _window(self, window: float) -> int:
        positive("window", window, "s")
        w = int(round(window / self.sample_time))
        w = max(w + (w + 1) % 2, 5)  # odd, >= 5 for a cubic
        if w > len(self):
            raise ValueError(f"window = {window} s: longer than the recording")
        return w

    def smoothed(self, window: float = DEFAULT_WINDOW_S) -> dict[str, np.ndarray]:
        """Zero-phase Savitzky-Golay smoothing [SG] (cubic, ``window`` seconds).

        Returns ``x, y, vx`` smoothed, ``ax`` = d vx/dt and ``v_xy`` = |d(x, y)/dt| from the
        same filter.
        """
        from scipy.signal import savgol_filter  # late: scipy.signal costs ~60 MB to import

        w = self._window(window)
        h = self.sample_time
        out = {}
        for k in ("x", "y", "vx"):
            out[k] = savgol_filter(self.data[k], w, 3, mode="interp")
        out["ax"] = savgol_filter(self.data["vx"], w, 3, deriv=1, delta=h, mode="interp")
        dx = savgol_filter(self.data["x"], w, 3, deriv=1, delta=h, mode="interp")
        dy = savgol_filter(self.data["y"], w, 3, deriv=1, delta=h, mode="interp")
        out["v_xy"] = np.hypot(dx, dy)
        return out

    def track_points(self, window: float = DEFAULT_WINDOW_S):
        """Points of the driven path: on-track part (or the moving part without bounds),
        smoothed, kept every >= 0.5 m of travel (see :data:`PATH_POINT_SPACING_M`)."""
        from flatfree.tracks.loaders import TrackPoints

        part = self.on_track()
        sm = part.smoothed(window)
        keep = _spaced(sm["x"], sm["y"], PATH_POINT_SPACING_M)
        x, y = sm["x"][keep], sm["y"][keep]
        nan = np.full_like(x, np.nan)
        return TrackPoints(self.name, f"{self.source} (driven path)", x, y, nan, nan.copy(), False)

    def path(self, *, window: float = DEFAULT_WINDOW_S, ds: float = DEFAULT_DS,
             smoothing_length: float = DEFAULT_SMOOTHING_LENGTH) -> Track:
        """The driven path as an open :class:`Track` (see :meth:`track_points`); several laps
        of an oval lie side by side, which the local Frenet search handles."""
        p = self.track_points(window)
        return Track.from_points(p.x, p.y, closed=False, ds=ds, smoothing_length=smoothing_length,
                                 name=f"{self.name} path", source=p.source)

    def reference(
        self,
        *,
        window: float = DEFAULT_WINDOW_S,
        dt: float | None = None,
        path: Track | None = None,
        ds: float = DEFAULT_DS,
        smoothing_length: float = DEFAULT_SMOOTHING_LENGTH,
    ) -> Reference:
        """The recording as a :class:`Reference` (time from 0 at the first sample).

        Geometry (x, y, psi, kappa, dkappa/ds, widths) is that of the driven path at the
        arc length s(t) of the smoothed position; vx is the smoothed recorded vx, ax its
        derivative, r = vx kappa and r_dot = ax kappa + vx^2 dkappa/ds like every reference;
        e_y reference is 0. Extras keep the recording: ``delta_recorded`` (front road-wheel
        steer, raw), ``psi_recorded`` (unwrapped phi), ``r_recorded`` (omega), ``vx_recorded``,
        ``ax_recorded``, ``x_recorded``, ``y_recorded`` (raw), ``t_recording`` (time in the file).

        Use it on a selection, e.g. ``load_recording("LVMS_23_01_04_B").on_track().reference()``.

        Parameters
        ----------
        window : float
            Savitzky-Golay window [s].
        dt : float, optional
            Time step of the reference [s]; default the recording's (0.04 s). Other steps, and
            recordings whose time stamps are not uniform to 0.1 %, are interpolated (cubic spline
            of s(t) and vx(t), whose derivative gives ax; linear for the extras).
        path : Track, optional
            The path to follow (default :meth:`path`, built from this selection).
        """
        sm = self.smoothed(window)
        trk = path if path is not None else self.path(window=window, ds=ds,
                                                      smoothing_length=smoothing_length)
        proj = trk.project(sm["x"], sm["y"], self.psi, s0=None)
        s = proj["s"]
        t_rec = self.t - self.t[0]
        nan = np.full(len(self), np.nan)
        extras = {
            "delta_recorded": self.data["delta"],
            "psi_recorded": self.psi,
            "r_recorded": self.data.get("omega", nan),
            "vx_recorded": self.data["vx"],
            "ax_recorded": self.data.get("ax", nan),
            "x_recorded": self.data["x"],
            "y_recorded": self.data["y"],
            "t_recording": self.t,
        }
        vx, ax = sm["vx"], sm["ax"]
        steps = np.diff(self.t)
        uniform = np.abs(steps - self.sample_time).max() < 1e-3 * self.sample_time
        if dt is None and not uniform:  # a user's file with jittery time stamps: resample
            dt = self.sample_time
        if dt is not None and not (uniform and math.isclose(positive("dt", dt, "s"),
                                                              self.sample_time)):
            tn = np.arange(int(math.floor(t_rec[-1] / dt + 1e-9)) + 1) * dt
            s = CubicSpline(t_rec, s)(tn)
            cv = CubicSpline(t_rec, vx)
            vx, ax = cv(tn), cv(tn, 1)
            extras = {k: np.interp(tn, t_rec, v) for k, v in extras.items()}
            t_rec = tn
        else:  # uniform to 0.1 %: use the exact grid (epoch times carry ~1e-7 s rounding)
            t_rec = np.arange(len(t_rec)) * self.sample_time
        geo = path_eval_many(trk.geometry, trk.closed, np.ascontiguousarray(s))
        tab = np.zeros((t_rec.shape[0], N_RS))
        tab[:, RS.T] = t_rec
        tab[:, RS.S] = s
        tab[:, RS.S_PATH] = s
        tab[:, RS.X] = geo[:, 0]
        tab[:, RS.Y] = geo[:, 1]
        tab[:, RS.PSI] = geo[:, 2]
        tab[:, RS.KAPPA] = geo[:, 3]
        tab[:, RS.DKAPPA_DS] = geo[:, 4]
        tab[:, RS.VX] = vx
        tab[:, RS.AX] = ax
        tab[:, RS.R] = vx * geo[:, 3]
        tab[:, RS.R_DOT] = ax * geo[:, 3] + vx * vx * geo[:, 4]
        tab[:, RS.W_LEFT] = geo[:, 5]
        tab[:, RS.W_RIGHT] = geo[:, 6]
        return Reference(name=self.name, path=trk, line=trk, table=tab, extras=extras)


def _spaced(x: np.ndarray, y: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of points at least ``spacing`` apart along the sequence (first point kept)."""
    keep = [0]
    lx, ly = x[0], y[0]
    for i in range(1, x.shape[0]):
        if math.hypot(x[i] - lx, y[i] - ly) >= spacing:
            keep.append(i)
            lx, ly = x[i], y[i]
    return np.asarray(keep)


def _lvms_bounds() -> tuple[np.ndarray, np.ndarray]:
    out = []
    for fname in _io.LVMS_BOUNDS:
        raw = _io.read_csv(_io.bundled_recording_file(fname), fname)
        x, y = raw.col("x"), raw.col("y")
        if _io.validate_polyline(x, y, raw.where, raw.source, short=raw.line):
            x, y = x[:-1], y[:-1]
        out.append(np.column_stack([x, y]))
    return out[0], out[1]


def load_recording(name_or_path: str | Path = "LVMS_23_01_04_B") -> Recording:
    """Load a bundled recording by name (case-insensitive) or a recording CSV by path.

    The bundled ``LVMS_23_01_04_B`` (Dallara AV-21 at Las Vegas Motor Speedway, 25 Hz, GPL-3.0
    [rec]) comes with the LVMS track bounds. Errors name the file and line.
    """
    file, display = _io.resolve(name_or_path, "recording")
    raw = _io.read_csv(file, display)
    if raw.fmt != "recording":
        raise ValueError(
            f"{display}: not a recording (header must name time, x, y, vx, phi, delta)"
        )
    return Recording.from_raw(raw, Path(display).stem,
                              bundled=not Path(name_or_path).is_file())
