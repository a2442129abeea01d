"""Tracks and reference trajectories: real track geometry, recorded driving, classic maneuvers.

Flow::

    load_track("Spa") ──► Track ──► speed_profile(track, SpeedLimits()) ──► make_reference(...)
    load_recording("LVMS_23_01_04_B").on_track().reference()          ──► Reference
    circle_reference / speed_step_reference / double_lane_change_reference ──► Reference
    Reference ──► reference_states_3dof(ref, cf=..., ...) (Vy, r, steer, flat outputs)

In the simulation loop: ``frenet_project(track.geometry, track.closed, x, y, psi, seg)``
(compiled, O(1) amortised, local search) and ``sample_reference(ref.table, t, out)``.

Conventions: ISO 8855 (x forward, y left, yaw counter-clockwise), SI units, kappa > 0 turning
left, e_y > 0 left of the path, e_psi = psi - psi_path.

Bundled data (``flatfree/data``): six TUMFTM race tracks (LGPL-3.0, derived from OpenStreetMap,
"(c) OpenStreetMap contributors") and the LVMS recording of an IAC Dallara AV-21 (GPL-3.0);
see ``flatfree/data/README.md``.
"""

from flatfree.tracks._io import raceline_names, recording_names, track_names
from flatfree.tracks.geometry import (
    DEFAULT_DS,
    DEFAULT_SMOOTHING_LENGTH,
    GC,
    FrenetProjector,
    Track,
    frenet_init,
    frenet_project,
    lateral_deviation_acceleration,
    lateral_deviation_acceleration_kernel,
    path_eval,
    path_eval_many,
    progress,
    project_points,
)
from flatfree.tracks.loaders import TrackPoints, load_track, read_track_points
from flatfree.tracks.maneuvers import (
    Gate,
    circle_reference,
    circle_track,
    double_lane_change_reference,
    double_lane_change_track,
    iso3888_1_gates,
    speed_step_reference,
    straight_track,
)
from flatfree.tracks.recording import Recording, load_recording
from flatfree.tracks.reference import (
    RS,
    LateralReference,
    Reference,
    make_reference,
    reference_states_3dof,
    sample_reference,
)
from flatfree.tracks.speed import (
    J_LAT_HANDLING,
    SpeedLimits,
    SpeedProfile,
    constant_speed_profile,
    drive_acceleration,
    jerk_speed_cap,
    speed_profile,
    top_speed,
)

__all__ = [
    "DEFAULT_DS",
    "DEFAULT_SMOOTHING_LENGTH",
    "GC",
    "J_LAT_HANDLING",
    "RS",
    "FrenetProjector",
    "Gate",
    "LateralReference",
    "Recording",
    "Reference",
    "SpeedLimits",
    "SpeedProfile",
    "Track",
    "TrackPoints",
    "circle_reference",
    "circle_track",
    "constant_speed_profile",
    "double_lane_change_reference",
    "double_lane_change_track",
    "drive_acceleration",
    "frenet_init",
    "frenet_project",
    "iso3888_1_gates",
    "jerk_speed_cap",
    "lateral_deviation_acceleration",
    "lateral_deviation_acceleration_kernel",
    "load_recording",
    "load_track",
    "make_reference",
    "path_eval",
    "path_eval_many",
    "progress",
    "project_points",
    "raceline_names",
    "read_track_points",
    "recording_names",
    "reference_states_3dof",
    "sample_reference",
    "speed_profile",
    "speed_step_reference",
    "straight_track",
    "top_speed",
    "track_names",
]
