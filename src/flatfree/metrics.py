"""Tracking metrics of a closed-loop run: one function, used by every comparison.

Definitions (the same for every controller, so that comparisons are fair):

- **lateral error** [m]: the true (not measured) signed distance of the CoG from the reference
  path, left positive (signal ``lateral_error``). The reference path is the path offset by the
  reference's lateral deviation ``e_y_ref(s)`` (``reference.lateral_offset_m``, a merge into
  the path): ``lateral_error = e_y - e_y_ref``, where the signal ``e_y`` is the distance from
  the track's own line.
- **yaw error** [rad, reported in deg]: the vehicle's yaw minus the reference yaw, wrapped to
  (-pi, pi] (signal ``yaw_error``). The reference yaw is the recorded yaw for a recorded
  reference (the recording's own heading column, unwrapped; the LVMS recording's follows its
  course, signed median difference -0.03 deg (its PROVENANCE.md), so the recorded car's
  sideslip is not in it); for a track
  reference it is the path heading corrected by the reference sideslip angle of the 3DoF
  model along the path, beta_ref = atan(Vy_ref / Vx_ref): comparing with the
  bare path heading would count the car's own sideslip as error. "Along the path" is taken
  exactly: the linear-tyre 3DoF model whose CoG follows the path at the reference speed
  (:func:`flatfree.tracks.reference_states_3dof`, ``method="path"``; its yaw rate is
  ``V kappa - beta_ref'``, not the path's ``V kappa``). With ISO 8855 signs the course
  angle (direction of the CoG velocity) is yaw + beta, so a car whose velocity follows the path
  has the yaw ``path heading - beta_ref`` (the issue's "plus" is the same correction written
  with the opposite sign convention for the sideslip angle).
- **course error** [rad, reported in deg; optional signal ``course_error``]: the direction of
  the CoG velocity minus the path heading. No sideslip model enters it: it is the heading figure
  a steering law controls when it keeps the CoG on the path, and yaw error = course error -
  (beta - beta_ref) separates the controller's part from the car's sideslip against the
  reference model's (benchmarks/README.md "Closed loop").
- **speed error** [m/s]: ``vx - vx_ref``.
- **steering rate** [rad/s]: the time derivative of the applied steer angle ``steer``
  (finite differences on the logged grid: a log coarser than the control period averages the
  rate over each log interval, which hides part of a steer that chatters between control
  steps; log every control step to see it at the control rate).
- **torque effort** [N m]: the RMS of the applied wheel torque ``torque``; and its rate
  [N m/s], the RMS of the time derivative of ``torque`` (finite differences on the logged grid,
  as the steering rate), which shows a chattering torque that the RMS hides.

All errors are taken over the whole run after a start-up interval ``startup_s`` (the same for
every controller); the default is :data:`DEFAULT_STARTUP_S`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from flatfree._validate import nonnegative, real_array
from flatfree._warn import warn
from flatfree.trajectory import Trajectory

__all__ = ["DEFAULT_STARTUP_S", "Metrics", "compute_metrics", "wrap_angle"]

#: Start-up interval excluded from every error metric [s] (controllers' windows fill, and the
#: initial state settles on the reference).
DEFAULT_STARTUP_S = 1.0


def wrap_angle(angle):
    """Wrap an angle [rad] (scalar or array) to (-pi, pi]."""
    a = real_array("angle", angle)
    w = -((-a + np.pi) % (2.0 * np.pi) - np.pi)
    return float(w) if np.ndim(angle) == 0 else w


@dataclass(frozen=True, slots=True)
class Metrics:
    """Metrics of one run; field names carry their units (JSON keys of the CLI)."""

    status: str
    duration_s: float
    lateral_error_max_m: float
    lateral_error_rms_m: float
    yaw_error_max_deg: float
    yaw_error_rms_deg: float
    speed_error_rms_mps: float
    steer_rate_rms_radps: float
    steer_rate_max_radps: float
    torque_rms_nm: float
    real_time_factor: float
    course_error_max_deg: float = math.nan  # NaN when the trajectory has no course_error
    torque_rate_rms_nmps: float = math.nan

    def to_dict(self) -> dict[str, float | str]:
        """Plain dict (JSON-ready; non-finite numbers become None)."""
        out: dict[str, float | str] = {}
        for k, v in asdict(self).items():
            out[k] = None if isinstance(v, float) and not math.isfinite(v) else v
        return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def _max_abs(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if x.size else math.nan


def no_sample_after_startup(traj: Trajectory, startup_s: float) -> bool:
    """True when no sample of ``traj`` lies at or after the start-up interval (``startup_s`` [s]
    from its first sample; an empty trajectory has none): every error metric of
    :func:`compute_metrics` is then NaN."""
    t = traj.time
    return not t.size or not bool(t[-1] >= t[0] + startup_s)


def compute_metrics(traj: Trajectory, *, startup_s: float = DEFAULT_STARTUP_S) -> Metrics:
    """Tracking metrics of a trajectory (definitions in the module docstring).

    Parameters
    ----------
    traj
        Needs the signals ``lateral_error`` [m], ``yaw_error`` [rad], ``vx`` and ``vx_ref``
        [m/s], ``steer`` [rad] and ``torque`` [N m]; uses ``course_error`` [rad] if present.
        ``meta["real_time_factor"]`` is reported when present (NaN otherwise).
    startup_s
        Start-up interval excluded from the errors [s], counted from the first sample.

    Returns
    -------
    Metrics
        NaN where no sample lies after the start-up interval (status, duration and real-time
        factor are still reported).

    Warns
    -----
    RuntimeWarning
        When no sample lies after the start-up interval (:func:`no_sample_after_startup`: the
        log ends within it, or is empty), naming the log's last time and ``startup_s``: every
        error metric is then NaN. When one sample only lies after it: the rates (a difference
        of two samples) are then NaN.

    Notes
    -----
    A run's log holds the samples at ``k log_dt_s`` before its end: the last of a run of
    ``duration_s`` is at ``duration_s - log_dt_s``, and a run that stops (left the track,
    non-finite state) at ``status_time`` has its last sample at or before it, not the step
    that crossed.
    """
    if not isinstance(traj, Trajectory):
        raise ValueError(f"traj = {traj!r:.60}: expected a flatfree.Trajectory "
                         "(simulate's result, or Trajectory.from_parquet / from_csv)")
    startup_s = nonnegative("startup_s", startup_s, "s")
    for name in ("lateral_error", "yaw_error", "vx", "vx_ref", "steer", "torque"):
        if name not in traj:
            raise ValueError(f"trajectory has no signal {name!r} needed by compute_metrics")
    if no_sample_after_startup(traj, startup_s):
        t = traj.time
        if t.size:
            start = "" if t[0] == 0.0 else f" from the first sample at t = {t[0]:g} s"
            end = (f"the log ends at t = {t[-1]:g} s, within the start-up interval of "
                   f"startup_s = {startup_s:g} s{start} that the metrics leave out")
        else:
            end = f"the trajectory has no sample (startup_s = {startup_s:g} s)"
        if not traj.completed:
            end += f" (the run stopped at t = {traj.status_time:g} s: {traj.status.value})"
        warn(f"compute_metrics: every metric is NaN but status, duration and real-time "
             f"factor: {end}; simulate longer or pass a shorter startup_s", RuntimeWarning)
    t0 = traj.time[0] if len(traj) else 0.0
    part = traj.after(t0 + startup_s)
    if len(part) == 1:
        warn(f"compute_metrics: one sample only (t = {part.time[0]:g} s) after the start-up "
             f"interval of startup_s = {startup_s:g} s: the steer and torque rates, "
             "differences of two samples, are NaN; simulate longer or pass a shorter "
             "startup_s", RuntimeWarning)
    ey = part["lateral_error"]
    epsi = np.degrees(wrap_angle(part["yaw_error"]))
    ev = part["vx"] - part["vx_ref"]
    t = part.time
    steer_rate = np.diff(part["steer"]) / np.diff(t) if t.size > 1 else np.empty(0)
    torque_rate = np.diff(part["torque"]) / np.diff(t) if t.size > 1 else np.empty(0)
    course = (np.degrees(wrap_angle(part["course_error"])) if "course_error" in traj
              else np.empty(0))
    return Metrics(
        status=traj.status.value,
        duration_s=traj.duration,
        lateral_error_max_m=_max_abs(ey),
        lateral_error_rms_m=_rms(ey),
        yaw_error_max_deg=_max_abs(epsi),
        yaw_error_rms_deg=_rms(epsi),
        speed_error_rms_mps=_rms(ev),
        steer_rate_rms_radps=_rms(steer_rate),
        steer_rate_max_radps=_max_abs(steer_rate),
        torque_rms_nm=_rms(part["torque"]),
        real_time_factor=float(traj.meta.get("real_time_factor", math.nan)),
        course_error_max_deg=_max_abs(course),
        torque_rate_rms_nmps=_rms(torque_rate),
    )
