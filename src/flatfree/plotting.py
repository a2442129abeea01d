"""Figures: the paper's Figures 2-6 and two more, each drawn into an Axes the caller gives.

Every ``plot_*`` function takes a matplotlib ``Axes`` first, draws into it and returns it; none
creates a window or calls ``plt.show()``. Runs are passed as a mapping ``label -> Trajectory``
(:class:`flatfree.trajectory.Trajectory`) and signals are read by name; a signal that a run did
not log is skipped for that run (the figure says so in its legend), never guessed.

===================================  ===========================================================
function                             figure
===================================  ===========================================================
:func:`plot_mismatch`                paper Fig. 2: flatness control, nominal vs mismatched Cf, Cr
:func:`plot_cornering_stiffness`     paper Fig. 3: effective Fy/alpha of each axle, braking in a
                                     turn (data: :func:`braking_in_turn`, 10DoF model)
:func:`plot_paths`                   paper Fig. 4: desired vs actual path, zoom on the worst corner
:func:`plot_lateral_error`,          paper Fig. 5: lateral and yaw errors over time
:func:`plot_yaw_error`
:func:`plot_torque`, :func:`plot_steer`  paper Fig. 6: wheel torque and steer against the
                                     reference or recorded ones
:func:`plot_f_estimate`              the estimated F of each model-free loop over time
:func:`plot_track_map`               a track map coloured by the lateral error
===================================  ===========================================================

:func:`new_figure` makes a figure without pyplot (no global state) and :func:`save_figure`
writes it as PNG and SVG.

Conventions: SI inside; axes labels carry the display unit (cm, deg) where the paper uses it.

References
----------
[paper] the paper (docs/README.md) (Section 3.1, Figs. 2-3; Section 4, Figs. 4-6).
[NOTES] docs/NOTES.md, "Results to compare with".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from flatfree.metrics import DEFAULT_STARTUP_S, wrap_angle
from flatfree.trajectory import Trajectory

__all__ = [
    "braking_in_turn",
    "new_figure",
    "plot_cornering_stiffness",
    "plot_f_estimate",
    "plot_lateral_error",
    "plot_mismatch",
    "plot_paths",
    "plot_steer",
    "plot_torque",
    "plot_track_map",
    "plot_yaw_error",
    "save_figure",
]

Runs = Mapping[str, Trajectory]
#: Grey of the reference curves (the paper draws references in grey).
REFERENCE_COLOR = "0.55"
_M_TO_CM = 100.0


def new_figure(width_in: float = 7.0, height_in: float = 4.0, *, nrows: int = 1,
               ncols: int = 1) -> tuple[Figure, np.ndarray]:
    """A figure and its axes (always a 2-D array), made without pyplot."""
    if not (width_in > 0 and height_in > 0):
        raise ValueError(f"figure size {width_in!r} x {height_in!r} in: must be positive")
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def save_figure(fig: Figure, out_dir: str | Path, stem: str, *, dpi: int = 110) -> list[Path]:
    """Write ``fig`` as ``out_dir/stem.png`` and ``out_dir/stem.svg``; return the two paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{stem}.png", out / f"{stem}.svg"]
    fig.savefig(paths[0], dpi=dpi)
    fig.savefig(paths[1])
    return paths


def _check_runs(runs: Runs) -> Runs:
    if not isinstance(runs, Mapping):
        raise ValueError(f"runs = {runs!r}: expected a mapping label -> Trajectory")
    for label, tr in runs.items():
        if not isinstance(tr, Trajectory):
            raise ValueError(f"runs[{label!r}] = {tr!r}: expected a Trajectory")
    return runs


def _signal_over_time(ax: Axes, runs: Runs, name: str, scale: float, *, wrap: bool = False,
                      lw: float = 1.0) -> list[str]:
    """Plot ``scale * signal`` of each run; return the labels of runs that lack the signal."""
    missing = []
    for label, tr in _check_runs(runs).items():
        if name not in tr:
            missing.append(label)
            continue
        v = tr[name]
        if wrap:
            v = wrap_angle(v)
        ax.plot(tr.time, scale * np.asarray(v), lw=lw, label=str(label))
    return missing


def _finish(ax: Axes, missing: Sequence[str], name: str, *, legend: bool = True) -> Axes:
    if missing:
        ax.plot([], [], " ", label=f"no {name}: {', '.join(map(str, missing))}")
    ax.grid(alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="best")
    return ax


def _reference_xy(reference) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, y)`` of a reference given as a pair of arrays or as an object with x and y."""
    if reference is None:
        return None
    if isinstance(reference, tuple | list) and len(reference) == 2:
        x, y = reference
    else:
        try:
            x, y = reference["x"], reference["y"]
        except (TypeError, KeyError, IndexError):
            x, y = getattr(reference, "x", None), getattr(reference, "y", None)
    if x is None or y is None:
        raise ValueError("reference: expected (x, y) arrays, or an object with x and y")
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"reference: x {x.shape} and y {y.shape} must be 1-D of equal length")
    return x, y


# ------------------------------------------------------------------------------------------
# Figure 4: paths
# ------------------------------------------------------------------------------------------
def worst_point(runs: Runs, *, startup_s: float = DEFAULT_STARTUP_S) -> tuple[str, int] | None:
    """``(label, sample)`` of the largest |lateral_error| over all runs after the start-up."""
    best: tuple[float, str, int] | None = None
    for label, tr in _check_runs(runs).items():
        if "lateral_error" not in tr or len(tr) == 0:
            continue
        e = np.abs(np.asarray(tr["lateral_error"]))
        e = np.where(tr.time >= tr.time[0] + startup_s, e, -np.inf)
        e = np.where(np.isfinite(e), e, -np.inf)
        i = int(np.argmax(e))
        if np.isfinite(e[i]) and (best is None or e[i] > best[0]):
            best = (float(e[i]), label, i)
    return None if best is None else (best[1], best[2])


#: Inset rectangles (axes fraction) of :func:`plot_paths` per corner; a margin at the axes'
#: edges leaves room for the inset's own tick labels.
_INSET_RECTS = {
    "lower right": [0.62, 0.07, 0.35, 0.35],
    "lower left": [0.08, 0.07, 0.35, 0.35],
    "upper left": [0.08, 0.58, 0.35, 0.35],
    "upper right": [0.62, 0.58, 0.35, 0.35],
}


def _corners_by_crowding(ax: Axes, runs: Runs, ref) -> list[str]:
    """The corners of :data:`_INSET_RECTS`, fewest path points under them first (ties keep
    the dict's order: lower right first)."""
    ax.apply_aspect()  # the limits the figure will be drawn with
    pts = [np.column_stack((ref[0], ref[1]))] if ref is not None else []
    pts += [np.column_stack((tr["x"], tr["y"])) for tr in runs.values()
            if "x" in tr and "y" in tr]
    xy = np.concatenate(pts) if pts else np.empty((0, 2))
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    fx, fy = (xy[:, 0] - x0) / (x1 - x0), (xy[:, 1] - y0) / (y1 - y0)  # axes fraction
    counts = {}
    for name, (left, bottom, w, h) in _INSET_RECTS.items():
        counts[name] = int(np.count_nonzero((fx >= left) & (fx <= left + w) & (fy >= bottom)
                                            & (fy <= bottom + h)))
    return sorted(counts, key=counts.__getitem__)


def plot_paths(ax: Axes, runs: Runs, *, reference=None, zoom: bool = True,
               zoom_half_width_m: float = 25.0, startup_s: float = DEFAULT_STARTUP_S) -> Axes:
    """Desired vs actual path (paper Fig. 4), with an inset zoomed on the worst corner.

    Parameters
    ----------
    ax : Axes
    runs : mapping label -> Trajectory
        Each needs ``x`` and ``y`` [m]; ``lateral_error`` [m] locates the worst corner.
    reference : (x, y) arrays, or an object with ``x`` and ``y`` (a Track, a Reference)
        The desired path, drawn thick and grey.
    zoom : bool
        Add an inset around the sample of largest |lateral_error| of all runs (after
        ``startup_s``), ``zoom_half_width_m`` each side; no inset when no run has that signal.
        The inset takes the corner of the axes with the fewest path points under it, the
        legend the next one.
    """
    ref = _reference_xy(reference)
    if ref is not None:
        ax.plot(ref[0], ref[1], color=REFERENCE_COLOR, lw=4, label="reference", zorder=1)
    missing = []
    for label, tr in _check_runs(runs).items():
        if "x" not in tr or "y" not in tr:
            missing.append(label)
            continue
        ax.plot(tr["x"], tr["y"], lw=1.0, label=str(label), zorder=2)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="X [m]", ylabel="Y [m]", title="desired and actual paths")
    _finish(ax, missing, "x, y")
    where = worst_point(runs, startup_s=startup_s) if zoom else None
    if where is not None and "x" in runs[where[0]]:
        label, i = where
        cx, cy = float(runs[label]["x"][i]), float(runs[label]["y"][i])
        if math.isfinite(cx) and math.isfinite(cy):
            corners = _corners_by_crowding(ax, runs, ref)
            ins = ax.inset_axes(_INSET_RECTS[corners[0]])
            if ax.get_legend() is not None:  # the legend to the next emptiest corner
                ax.legend(fontsize=8, loc=corners[1])
            if ref is not None:
                ins.plot(ref[0], ref[1], color=REFERENCE_COLOR, lw=4)
            for tr in runs.values():
                if "x" in tr and "y" in tr:
                    ins.plot(tr["x"], tr["y"], lw=1.0)
            h = float(zoom_half_width_m)
            ins.set_xlim(cx - h, cx + h)
            ins.set_ylim(cy - h, cy + h)
            ins.set_aspect("equal", adjustable="box")
            ins.tick_params(labelsize=6)
            ins.set_title(f"worst corner ({label})", fontsize=7)
            ax.indicate_inset_zoom(ins, edgecolor="0.3")
    return ax


# ------------------------------------------------------------------------------------------
# Figure 5: errors
# ------------------------------------------------------------------------------------------
def plot_lateral_error(ax: Axes, runs: Runs) -> Axes:
    """Lateral error [cm] over time (paper Fig. 5, top); signal ``lateral_error`` [m]."""
    missing = _signal_over_time(ax, runs, "lateral_error", _M_TO_CM)
    ax.axhline(0.0, color="0.3", lw=0.5)
    ax.set(xlabel="t [s]", ylabel="lateral error [cm]", title="lateral error")
    return _finish(ax, missing, "lateral_error")


def plot_yaw_error(ax: Axes, runs: Runs) -> Axes:
    """Yaw error [deg] over time (paper Fig. 5, bottom); signal ``yaw_error`` [rad], wrapped."""
    missing = _signal_over_time(ax, runs, "yaw_error", math.degrees(1.0), wrap=True)
    ax.axhline(0.0, color="0.3", lw=0.5)
    ax.set(xlabel="t [s]", ylabel="yaw error [deg]", title="yaw error")
    return _finish(ax, missing, "yaw_error")


# ------------------------------------------------------------------------------------------
# Figure 6: inputs
# ------------------------------------------------------------------------------------------
def _reference_series(reference, what: str) -> tuple[np.ndarray, np.ndarray] | None:
    if reference is None:
        return None
    try:
        t, v = reference
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a pair (time [s], values)") from None
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"{what}: time {t.shape} and values {v.shape} must be 1-D, equal length")
    return t, v


def _reference_on_top(ax: Axes, t: np.ndarray, v: np.ndarray, label: str) -> None:
    """A recorded input drawn black and dashed above the runs' traces: the commands of a noisy
    run fill a band that hid the thick grey line under them (paper Fig. 6)."""
    ax.plot(t, v, color="k", lw=1.4, ls="--", label=label, zorder=3)


def plot_torque(ax: Axes, runs: Runs, *, reference=None,
                reference_label: str = "reference") -> Axes:
    """Applied wheel torque [N m] of each run (paper Fig. 6, top).

    ``reference``: a pair ``(time [s], torque [N m])`` (e.g. a recorded or feed-forward
    torque), drawn on top of the runs (:func:`_reference_on_top`).
    """
    ref = _reference_series(reference, "reference")
    missing = _signal_over_time(ax, runs, "torque", 1.0)
    if ref is not None:
        _reference_on_top(ax, ref[0], ref[1], reference_label)
    ax.set(xlabel="t [s]", ylabel="wheel torque [N m]", title="wheel torque")
    return _finish(ax, missing, "torque")


def plot_steer(ax: Axes, runs: Runs, *, reference=None,
               reference_label: str = "recorded") -> Axes:
    """Applied front road-wheel steer [deg] of each run (paper Fig. 6, bottom).

    ``reference``: a pair ``(time [s], steer [rad])``, e.g. the recorded driver's steer of a
    recording (``Reference.extras["delta_recorded"]``), drawn on top of the runs
    (:func:`_reference_on_top`).
    """
    ref = _reference_series(reference, "reference")
    missing = _signal_over_time(ax, runs, "steer", math.degrees(1.0))
    if ref is not None:
        _reference_on_top(ax, ref[0], np.degrees(ref[1]), reference_label)
    ax.set(xlabel="t [s]", ylabel="steer [deg]", title="front road-wheel steer")
    return _finish(ax, missing, "steer")


# ------------------------------------------------------------------------------------------
# Figure 2: flatness control with mismatched stiffness
# ------------------------------------------------------------------------------------------
def plot_mismatch(ax: Axes, runs: Runs, *, signal: str = "lateral_error") -> Axes:
    """Flatness-based control, nominal vs mismatched cornering stiffness (paper Fig. 2).

    ``runs`` maps a case label (e.g. ``"nominal"``, ``"0.3 Cf, 0.3 Cr"``) to its trajectory;
    ``signal`` is ``"lateral_error"`` (drawn in cm) or ``"yaw_error"`` (deg).
    """
    if signal == "lateral_error":
        missing = _signal_over_time(ax, runs, signal, _M_TO_CM)
        ax.set(ylabel="lateral error [cm]")
    elif signal == "yaw_error":
        missing = _signal_over_time(ax, runs, signal, math.degrees(1.0), wrap=True)
        ax.set(ylabel="yaw error [deg]")
    else:
        raise ValueError(f"signal = {signal!r}: must be 'lateral_error' or 'yaw_error'")
    ax.axhline(0.0, color="0.3", lw=0.5)
    ax.set(xlabel="t [s]", title="flatness-based control, nominal vs mismatched Cf, Cr")
    return _finish(ax, missing, signal)


# ------------------------------------------------------------------------------------------
# Figure 3: effective cornering stiffness while braking in a turn
# ------------------------------------------------------------------------------------------
#: Slip angles below this magnitude [rad] give no meaningful Fy/alpha (0/0): reported as NaN.
#: 0.1 deg: far below the 1-3 deg of the turn, far above the model's numerical noise.
MIN_SLIP_ANGLE_RAD = math.radians(0.1)


def braking_in_turn(vehicle: str = "peugeot406", *, speed_mps: float = 20.0,
                    ay_mps2: float = 4.0, decel_mps2: float = 5.0, t_brake_s: float = 3.0,
                    brake_duration_s: float = 2.0, duration_s: float = 6.0,
                    dt_s: float = 1e-3) -> dict[str, np.ndarray | float]:
    """Data of the paper's Fig. 3 from the 10DoF model: brake while turning, Fy/alpha per axle.

    The car drives at ``speed_mps`` with a constant steer that the linear single-track formula
    says gives ``ay_mps2``; a feed-forward torque balances drag and rolling resistance. At
    ``t_brake_s`` a brake torque ``m decel R`` is applied for ``brake_duration_s`` (steer held).
    The effective cornering stiffness of an axle is ``-(Fy_left + Fy_right) / mean(alpha)``
    (ISO sign; :meth:`flatfree.models.tendof.TenDoF.diagnostics`), NaN where
    ``|mean(alpha)| < MIN_SLIP_ANGLE_RAD``. The load transfer to the front axle while braking
    raises its effective stiffness and lowers the rear one: the paper's point that C_f and C_r
    vary with the dynamic load.

    Returns
    -------
    dict
        ``t`` [s], ``c_front``, ``c_rear`` [N/rad] (per axle), ``ax`` [m/s^2], ``brake``
        (bool array, brake on), and ``cf_nominal``, ``cr_nominal`` [N/rad] (the tyres'
        cornering stiffness at static load, two per axle).

    References
    ----------
    [paper] Section 3.1, Fig. 3. [VM] docs/VEHICLE_MODEL.md 5.4-5.5.
    """
    from flatfree.models.tendof import TenDoF, Wheel
    from flatfree.tires import cornering_stiffness
    from flatfree.units import G
    from flatfree.vehicles import load_vehicle

    for name, v in (("speed_mps", speed_mps), ("ay_mps2", ay_mps2), ("decel_mps2", decel_mps2),
                    ("brake_duration_s", brake_duration_s), ("duration_s", duration_s),
                    ("dt_s", dt_s)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r}: must be a finite number > 0")
    vp = load_vehicle(vehicle)
    model = TenDoF(vp)
    fzf, fzr = vp.static_axle_loads
    cf = 2.0 * cornering_stiffness(vp.tire_front, 0.5 * fzf)  # per axle [N/rad]
    cr = 2.0 * cornering_stiffness(vp.tire_rear, 0.5 * fzr)
    wb, m = vp.wheelbase, vp.mass
    k_us = m / wb * (vp.lr / cf - vp.lf / cr)  # understeer gradient [Raj] Ch. 3
    delta = ay_mps2 * (wb + k_us * speed_mps**2) / speed_mps**2  # linear single track
    cruise = vp.wheel_radius * (0.5 * vp.air_density * vp.drag_area * speed_mps**2
                                + vp.rolling_resistance * m * G)
    n = int(round(duration_s / dt_s))
    t = np.arange(n) * dt_s
    brake = (t >= t_brake_s) & (t < t_brake_s + brake_duration_s)
    tw = np.where(brake, -m * decel_mps2 * vp.wheel_radius, cruise)
    u = model.inputs(tw, np.full(n, delta))
    xs = model.simulate(model.initial_state(speed_mps), u, dt_s)[1:]
    d = model.diagnostics(xs, u)
    fy, alpha = d["fy"], d["alpha"]

    def eff(a: int, b: int) -> np.ndarray:
        am = 0.5 * (alpha[:, a] + alpha[:, b])
        c = -(fy[:, a] + fy[:, b]) / np.where(np.abs(am) < MIN_SLIP_ANGLE_RAD, np.nan, am)
        return c

    return {
        "t": t,
        "c_front": eff(int(Wheel.fl), int(Wheel.fr)),
        "c_rear": eff(int(Wheel.rl), int(Wheel.rr)),
        "ax": np.asarray(d["ax"]),
        "brake": brake,
        "cf_nominal": float(cf),
        "cr_nominal": float(cr),
    }


def plot_cornering_stiffness(ax: Axes, data: Mapping[str, np.ndarray | float]) -> Axes:
    """Effective cornering stiffness Fy/alpha of each axle over time (paper Fig. 3).

    ``data`` as returned by :func:`braking_in_turn` (keys ``t``, ``c_front``, ``c_rear``,
    optional ``brake``, ``cf_nominal``, ``cr_nominal``). Drawn in kN/rad, braking shaded.
    """
    for k in ("t", "c_front", "c_rear"):
        if k not in data:
            raise ValueError(f"data has no {k!r}: expected the output of braking_in_turn()")
    t = np.asarray(data["t"], dtype=float)
    ax.plot(t, np.asarray(data["c_front"]) / 1e3, lw=1.2, label="front axle Fy/alpha")
    ax.plot(t, np.asarray(data["c_rear"]) / 1e3, lw=1.2, label="rear axle Fy/alpha")
    if "cf_nominal" in data:
        ax.axhline(float(data["cf_nominal"]) / 1e3, color="C0", ls="--", lw=0.8,
                   label="front, static load")
    if "cr_nominal" in data:
        ax.axhline(float(data["cr_nominal"]) / 1e3, color="C1", ls="--", lw=0.8,
                   label="rear, static load")
    if "brake" in data:
        b = np.asarray(data["brake"], dtype=bool)
        if b.any():
            ax.fill_between(t, 0, 1, where=b, color="0.9", transform=ax.get_xaxis_transform(),
                            label="braking", zorder=0)
    ax.set(xlabel="t [s]", ylabel="cornering stiffness [kN/rad]",
           title="effective cornering stiffness, braking in a turn (10DoF)")
    return _finish(ax, [], "")


# ------------------------------------------------------------------------------------------
# Beyond the paper
# ------------------------------------------------------------------------------------------
def plot_f_estimate(ax: Axes, runs: Runs, *, loop: str = "lat") -> Axes:
    """Estimated F of each model-free loop over time (signals ``f_lon`` or ``f_lat``).

    ``loop``: ``"lon"`` (speed loop, m/s^2) or ``"lat"`` (lateral loop, whose unit depends on
    the controller: m/s^2 on natural outputs, kg m^2/s^2 on flat outputs; taken from each
    trajectory's ``units``). Runs whose F has another unit than the first run's are drawn
    against a second y axis on the right (``ax.twinx()``), so that neither hides the other.
    A run without the signal, or with no finite value of it (a controller without an F
    estimator), is listed as missing.
    """
    if loop not in ("lon", "lat"):
        raise ValueError(f"loop = {loop!r}: must be 'lon' or 'lat'")
    name = f"f_{loop}"
    missing = []
    axes: dict[str, Axes] = {}
    handles = []
    for i, (label, tr) in enumerate(_check_runs(runs).items()):
        if name not in tr or not np.isfinite(tr[name]).any():
            missing.append(label)
            continue
        unit = tr.units.get(name, "?")
        if unit not in axes:
            axes[unit] = ax if not axes else ax.twinx()
            axes[unit].set_ylabel(f"F [{unit}]" + (" (right)" if len(axes) > 1 else ""))
        (ln,) = axes[unit].plot(tr.time, tr[name], lw=0.8, color=f"C{i}",
                                label=f"{label} [{unit}]")
        handles.append(ln)
    what = "speed" if loop == "lon" else "lateral"
    ax.set(xlabel="t [s]", title=f"estimated F, {what} loop")
    if not axes:
        ax.set_ylabel("F")
    if missing:
        (ln,) = ax.plot([], [], " ", label=f"no {name}: {', '.join(map(str, missing))}")
        handles.append(ln)
    ax.grid(alpha=0.3)
    if handles:
        ax.legend(handles=handles, fontsize=8, loc="best")
    return ax


def plot_track_map(ax: Axes, traj: Trajectory, *, reference=None, cmap: str = "viridis",
                   colorbar: bool = True) -> Axes:
    """The driven path coloured by |lateral error| [cm].

    Needs the signals ``x``, ``y`` [m] and ``lateral_error`` [m]; ``reference`` (as in
    :func:`plot_paths`) is drawn wide and light underneath.
    """
    if not isinstance(traj, Trajectory):
        raise ValueError(f"traj = {traj!r}: expected a Trajectory")
    for k in ("x", "y", "lateral_error"):
        if k not in traj:
            raise ValueError(f"trajectory has no signal {k!r} needed by plot_track_map")
    ref = _reference_xy(reference)
    if ref is not None:
        ax.plot(ref[0], ref[1], color="0.8", lw=6, zorder=1)
    x, y = np.asarray(traj["x"]), np.asarray(traj["y"])
    e = np.abs(np.asarray(traj["lateral_error"])) * _M_TO_CM
    pts = np.column_stack([x, y]).reshape(-1, 1, 2)
    segs = np.concatenate([pts[:-1], pts[1:]], axis=1)
    lc = LineCollection(segs, cmap=cmap, lw=2.0, zorder=2)
    ev = 0.5 * (e[:-1] + e[1:]) if e.size > 1 else e
    lc.set_array(ev)
    ax.add_collection(lc)
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="X [m]", ylabel="Y [m]", title="track map, |lateral error|")
    if colorbar and ev.size:
        ax.figure.colorbar(lc, ax=ax, label="|lateral error| [cm]")
    ax.grid(alpha=0.3)
    return ax
