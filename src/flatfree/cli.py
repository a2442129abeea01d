"""The ``flatfree`` command line: reproduce the paper, run a scenario, list data, benchmark.

A thin layer (DESIGN.md): parse the options, build a :class:`~flatfree.scenario.Scenario`, call
:func:`flatfree.simulation.simulate`, :func:`flatfree.metrics.compute_metrics`,
:mod:`flatfree.plotting` and :mod:`flatfree.report`, write files. Commands::

    flatfree demo       the paper's scenarios, a table beside the paper's figures, a report
    flatfree run        one run (a TOML file, a named scenario, or options)
    flatfree tracks     the bundled tracks and recordings
    flatfree vehicles   the vehicle presets
    flatfree scenario new FILE   a commented TOML template (--from NAME: a named scenario)
    flatfree scenario list       the named scenarios
    flatfree bench      speed of the library on this machine

Exit codes: 0 success; 1 the run failed (its status is not ``completed``); 2 bad usage or bad
input (unknown name, malformed file, an option the chosen controller does not take, a feature
the closed loop does not provide yet). Messages go to stderr; ``--json`` prints exactly one JSON
object on stdout.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import math
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np

from flatfree import __version__
from flatfree._timing import best_time
from flatfree._warn import recording

__all__ = ["main", "count_corners", "SCENARIO_TEMPLATE"]

CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}
#: Keys every ``run --json`` object has (the issue's list, and a few more).
JSON_KEYS = ("controller", "track", "status", "lateral_error_max_m", "lateral_error_rms_m",
             "yaw_error_max_deg", "yaw_error_rms_deg", "speed_error_rms_mps",
             "real_time_factor")
#: The paper's three controllers, in the paper's order, and the named scenario of each.
PAPER_RUNS = (("flatness", "paper-flatness"), ("mfc-flat", "paper-mfc-flat"),
              ("mfc-natural", "paper"))
#: Row label of the natural-output controller with the inertial unit's F (``paper-imu``,
#: ``recorded-imu``), which ``demo`` runs beside the paper's three.
IMU_LABEL = "mfc-natural, imu F (beyond the paper)"
#: Default output folder of ``demo``.
DEFAULT_OUT = "flatfree-out"


class InputError(click.ClickException):
    """Bad usage or input: printed as ``Error: ...``, exit code 2."""

    exit_code = 2


def _fail(msg: str) -> InputError:
    return InputError(msg)


def _err(msg: str) -> None:
    click.echo(msg, err=True)


# ------------------------------------------------------------------------------------------
# Named scenarios (flatfree.scenarios, issue 7)
# ------------------------------------------------------------------------------------------
def _scenarios_module():
    try:
        import flatfree.scenarios as mod
    except ImportError as exc:  # pragma: no cover - depends on the build
        raise _fail(
            f"named scenarios need flatfree.scenarios, which this build lacks ({exc})") from exc
    return mod


def _named(name: str, **kw):
    mod = _scenarios_module()
    try:
        return mod.named_scenario(name, **kw)
    except ValueError as exc:
        raise _fail(str(exc)) from None


def _scenario_names_help() -> str:
    """A help paragraph naming every named scenario, from flatfree.scenarios.SCENARIO_NAMES
    (so it cannot miss one); wrapped here, as click would break the names at their hyphens."""
    from flatfree.scenario import NOISE_FREE_SUFFIX as sfx

    bases = [n for n in _scenarios_module().SCENARIO_NAMES if not n.endswith(sfx)]
    return "\b\n" + textwrap.fill(f"Named scenarios (`flatfree scenario list` describes them): "
                                  f"{', '.join(bases)}; each also as NAME{sfx}.", width=96,
                                  break_on_hyphens=False)


def _round_times(payload: dict[str, Any]) -> dict[str, Any]:
    """``payload`` with its times [s] (keys ending in ``_s``) rounded to 12 significant digits
    for printing: 19.99, not 19.990000000000002 (the binary rounding of the step sums)."""
    return {k: float(f"{v:.12g}") if k.endswith("_s") and isinstance(v, float) else v
            for k, v in payload.items()}


@contextlib.contextmanager
def _out_dir(out_dir: Path | None):
    """Create the output folder ``out_dir`` (None: none) and check that a file can be written
    in it, before the command spends its time: :class:`InputError` (exit 2) naming the folder
    if not. The folders it created are removed again if the command fails before writing into
    them."""
    created = [] if out_dir is None else [q for q in (out_dir, *out_dir.parents)
                                          if not q.exists()]
    try:
        if out_dir is not None:
            try:
                out_dir.mkdir(parents=True, exist_ok=True)
                with tempfile.TemporaryFile(dir=out_dir):
                    pass
            except OSError as exc:
                raise _fail(f"--out {out_dir}: cannot create or write this folder "
                            f"({exc.strerror or exc})") from None
        yield
    except BaseException:
        for q in created:  # deepest first; a folder written into is not empty: kept
            with contextlib.suppress(OSError):
                q.rmdir()
        raise


# ------------------------------------------------------------------------------------------
# the main group
# ------------------------------------------------------------------------------------------
@click.group(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree demo --out flatfree-out      the paper reproduced, report in flatfree-out/report.html
  flatfree run --controller mfc-natural --track Monza --json
  flatfree run paper-imu --track Spa    natural outputs, lateral F from the accelerometers
  flatfree run my_scenario.toml --seed 3 --out run1
  flatfree run --recording LVMS_23_01_04_B --json
  flatfree run paper-imu --set reference.j_lat_max=15 --set sensors.y.markov_order=2
  flatfree tracks
  flatfree scenario new my_scenario.toml

Exit codes: 0 success, 1 the run failed (status not completed), 2 bad usage or input.""")
@click.version_option(__version__, "-V", "--version", prog_name="flatfree")
def main() -> None:
    """flatfree: flatness-based and model-free control of autonomous cars."""


# ------------------------------------------------------------------------------------------
# tracks and vehicles
# ------------------------------------------------------------------------------------------
#: A corner is a stretch where the path's radius is below this [m] (|kappa| >= 1/R) ...
CORNER_RADIUS_M = 300.0
#: ... over at least this length [m] ...
CORNER_MIN_LENGTH_M = 15.0
#: ... and two such stretches turning the same way closer than this [m] are one corner.
CORNER_MERGE_GAP_M = 50.0


def count_corners(kappa: np.ndarray, ds: float, closed: bool) -> int:
    """Number of corners of a path sampled every ``ds`` metres with curvature ``kappa``.

    A corner is a maximal stretch with radius below :data:`CORNER_RADIUS_M` (``|kappa| >=
    1/R``) turning one way, at least :data:`CORNER_MIN_LENGTH_M` long; stretches turning the
    same way with a gap below :data:`CORNER_MERGE_GAP_M` count as one (a corner whose radius
    wobbles around the threshold). On a closed path a corner across the start counts once.
    This is a display convention of ``flatfree tracks``, not a racing definition.
    """
    k = np.asarray(kappa, dtype=float)
    if k.ndim != 1 or not (ds > 0):
        raise ValueError("count_corners: kappa must be 1-D and ds > 0")
    sign = np.where(np.abs(k) >= 1.0 / CORNER_RADIUS_M, np.sign(k), 0.0)
    runs: list[list[float]] = []  # [start index, stop index, sign]
    i = 0
    n = sign.size
    while i < n:
        if sign[i] == 0.0:
            i += 1
            continue
        j = i
        while j < n and sign[j] == sign[i]:
            j += 1
        runs.append([i, j, sign[i]])
        i = j
    merged: list[list[float]] = []
    gap = CORNER_MERGE_GAP_M / ds
    for r in runs:
        if merged and merged[-1][2] == r[2] and r[0] - merged[-1][1] < gap:
            merged[-1][1] = r[1]
        else:
            merged.append(list(r))
    if closed and len(merged) > 1 and merged[0][2] == merged[-1][2] \
            and merged[0][0] + (n - merged[-1][1]) < gap:
        last = merged.pop()
        merged[0][0] = last[0] - n  # wraps: length = stop - start stays right
    return sum(1 for a, b, _ in merged if (b - a) * ds >= CORNER_MIN_LENGTH_M)


_LICENSES = {
    "track": "LGPL-3.0 (TUMFTM racetrack-database; (c) OpenStreetMap contributors)",
    "LVMS": "GPL-3.0 (built from the bound files of the linklab-uva/deep-dynamics data)",
    "recording": "GPL-3.0 (linklab-uva/deep-dynamics)",
}


@main.command(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree tracks
  flatfree tracks --json""")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def tracks(as_json: bool) -> None:
    """The bundled tracks (length, corners, license) and recordings.

    A track name (case-insensitive) or the path of a CSV file (TUMFTM x_m, y_m, w_tr_right_m,
    w_tr_left_m; plain x, y; or the recording format) goes to `flatfree run --track`; a
    recording to `flatfree run --recording`. Corners: stretches of radius below
    300 m over at least 15 m (`flatfree.cli.count_corners`).
    """
    from flatfree.tracks import load_recording, load_track, recording_names, track_names

    rows = []
    for name in track_names():
        tr = load_track(name)
        rows.append({"name": name, "length_m": round(tr.length, 1),
                     "corners": count_corners(tr.kappa, tr.ds, tr.closed),
                     "closed": tr.closed,
                     "license": _LICENSES["LVMS" if name == "LVMS" else "track"]})
    recs = []
    for name in recording_names():
        rec = load_recording(name)
        t = rec.t
        recs.append({"name": name, "duration_s": round(float(t[-1] - t[0]), 1),
                     "samples": len(rec), "license": _LICENSES["recording"]})
    if as_json:
        click.echo(json.dumps({"tracks": rows, "recordings": recs}))
        return
    click.echo(f"{'track':12s} {'length km':>9s} {'corners':>8s}  {'loop':4s}  license")
    for r in rows:
        click.echo(f"{r['name']:12s} {r['length_m'] / 1000:9.3f} {r['corners']:8d}  "
                   f"{'yes' if r['closed'] else 'no':4s}  {r['license']}")
    click.echo("")
    click.echo(f"{'recording':18s} {'duration':>9s} {'samples':>8s}  license")
    for r in recs:
        click.echo(f"{r['name']:18s} {r['duration_s']:8.1f}s {r['samples']:8d}  {r['license']}")


@main.command(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree vehicles
  flatfree run --vehicle bmw320i --controller mfc-natural""")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def vehicles(as_json: bool) -> None:
    """The vehicle presets (sources: the TOML files in flatfree/vehicles/data)."""
    from flatfree.vehicles import load_vehicle, vehicle_names

    rows = []
    for name in vehicle_names():
        v = load_vehicle(name)
        rows.append({"name": name, "drive": v.drive, "mass_kg": v.mass,
                     "wheelbase_m": v.wheelbase, "iz_kgm2": v.iz,
                     "max_power_kw": v.max_power / 1000.0,
                     "tires": f"{v.tire_front.name} / {v.tire_rear.name}"})
    if as_json:
        click.echo(json.dumps({"vehicles": rows}))
        return
    click.echo(f"{'preset':14s} {'drive':6s} {'mass':>8s} {'wheelbase':>9s} {'Iz':>10s} "
               f"{'power':>7s}  tyres (front / rear)")
    for r in rows:
        click.echo(f"{r['name']:14s} {r['drive']:6s} {r['mass_kg']:6.0f}kg "
                   f"{r['wheelbase_m']:8.3f}m {r['iz_kgm2']:7.0f}kgm2 "
                   f"{r['max_power_kw']:5.0f}kW  {r['tires']}")


# ------------------------------------------------------------------------------------------
# scenario new
# ------------------------------------------------------------------------------------------
#: The peugeot406's algebraic tuning of session 21, as the scenario files written then hold it
#: (``flatfree run FILE --vehicle V`` retunes it for V as it does the current one).
_PEUGEOT_SESSION21 = {"alpha_lat": 52.0, "wn_lat": 7.6, "zeta_lat": 1.45, "wn_lat_speed": 40.0,
                      "wn_lat_ratio": 2.5, "denoise_yaw": 100}

SCENARIO_TEMPLATE = '''\
# A flatfree scenario: one closed-loop run. Run it with
#     flatfree run THIS_FILE.toml [--json] [--out DIR]
# The values below are those of the named scenario "paper" (`flatfree run paper`) but its
# name and description: the defaults of flatfree.scenario.Scenario, plus the sensor noise of
# flatfree.scenarios.REALISTIC_SENSORS (Scenario() itself has no [sensors.*] table: every
# channel exact). Every key is optional: a key left out takes the default of
# flatfree.scenario.Scenario, and a channel without a table is exact. Another named scenario
# as a file: `flatfree scenario new FILE --from NAME` (`flatfree scenario list`).
# SI units; a unit is part of a key's name where it is not obvious. A relative file path
# (vehicle, track, recording) is relative to this file's folder.

name = "my-scenario"
description = "as paper: the paper's car on Norisring, model-free control on natural outputs"
vehicle = "peugeot406"      # a preset (flatfree vehicles) or the path of a vehicle TOML file
plant = "10dof"             # "10dof" (validation model) or "3dof" (the paper's design model)
controller = "mfc-natural"  # "flatness", "mfc-flat", "mfc-natural"
noise = true                # false: every sensor noise-free (rates and delays kept)
seed = 0                    # seed of the sensor noise

# [vehicle_overrides]       # VehicleParams fields, SI: the car itself, the plant and the
#                           # controllers' models alike (no mismatch: cf_scale, cr_scale), e.g.
# mass = 1600.0

[controller_settings]       # the chosen controller's own settings; empty: its defaults
curvature_term = true       # mfc-natural: the peugeot406's tuning with the algebraic
alpha_lat = 48.9            # estimator (flatfree.scenarios.NATURAL_SETTINGS; remove these
wn_lat = 5.7                # nine lines for another controller, or for the defaults, which
zeta_lat = 1.36             # estimator_lat = "imu" uses)
wn_lat_speed = 0.0
window_lat = 185
denoise_lat = 84
yaw_damping = 0.35
denoise_yaw = 62
# flatness:    cf_scale = 0.3, cr_scale = 0.3 (the model's cornering stiffness, x nominal),
#              path_correction = false (the paper's design exactly: it drifts off the path)
# mfc-flat:    alpha_lon, kp_lon, ki_lon, window_lon, alpha_lat, kp_lat, ki_lat, window_lat,
#              path_correction, outer_wn, steer_min_speed (m/s; default 1.0)
# mfc-natural: alpha_lon, kp_lon, window_lon, alpha_lat, wn_lat, zeta_lat, window_lat,
#              wn_lat_speed, wn_lat_ratio (speed schedule), yaw_damping,
#              curvature_term (-Vx^2 kappa out of F), denoise_lat,
#              estimator_lat = "imu" (lateral F from the accelerometers; the
#              paper-imu scenario: the defaults and yaw_damping = 0.2,
#              denoise_yaw = 20),
#              imu_filter_s, observer_wn, observer_bias_wn,
#              correction_max (m/s^2; default 4.0; inf: no bound),
#              steer_min_speed (m/s; default 1.0: the steer held below it)
#              (dallara_av21: the defaults and alpha_lat = 60.0)

[reference]
track = "Norisring"         # a bundled track (flatfree tracks) or a CSV path;
                            # or, instead of track:  recording = "LVMS_23_01_04_B"
line = "centerline"         # or "raceline"
lateral_offset_m = 0.0
laps = 1
a_lat_max = 6.0             # speed profile: lateral acceleration limit [m/s^2]
a_drive_max = 3.0           # [m/s^2]
a_brake_max = 6.0           # [m/s^2]
v_max = 50.0                # [m/s]
mu = 1.0                    # friction the speed profile plans with [-]
j_lat_max = inf             # lateral jerk v^3 |dkappa/ds| [m/s^3]; inf: no limit; 15.0 keeps
                            # a rough path drivable at a small cost in lap time (its cost on
                            # the bundled tracks: flatfree.tracks.speed)
drive_limit = false         # true: also within the car's drive limit (power, torque, drag)
# closed = false            # a track file: open road (false) or loop (true); default: detected
# smoothing_length_m = 20.0 # a track's smoothing cut-off wavelength [m], 0: none; default
                            # 20 (LVMS 60)

[timing]
plant_dt_s = 0.001          # plant RK4 step
control_dt_s = 0.001        # controller period (a whole multiple of plant_dt_s); the
                            # controller's windows count samples tuned at 0.001 s: change
                            # it with `flatfree run --control-period S`, which rescales them
log_dt_s = 0.01             # logging period (a whole multiple of plant_dt_s)
startup_s = 1.0
# duration_s = 60.0         # default: until the path's end (at most 1.5 x the reference's
                            # duration + 5 s; Timing)

# one table per measured channel (x, y, psi, vx, vy, r, ax, ay): noise sigma, bias, rate,
# delay; a channel without a table is exact
[sensors.x]
noise_std = 0.001           # [m]
# markov_std = 0.01         # [m] a slow (Gauss-Markov) drift on top: its std,
# markov_tau_s = 60.0       # [s] its correlation time,
# markov_order = 2          # 1: first order (a random walk at short time scales), 2: smooth
[sensors.y]
noise_std = 0.001           # [m]
[sensors.psi]
noise_std = 0.0017          # [rad]
[sensors.vx]
noise_std = 0.05            # [m/s]
[sensors.vy]
noise_std = 0.02            # [m/s]
[sensors.r]
noise_std = 0.0017          # [rad/s]
[sensors.ax]
noise_std = 0.05            # [m/s^2] (used by estimator_lat = "imu")
[sensors.ay]
noise_std = 0.05            # [m/s^2]
bias = 0.01                 # [m/s^2]
# rate_hz = 100.0
# delay_s = 0.0

[actuators]
steer_tau_s = 0.0
steer_delay_s = 0.0
torque_tau_s = 0.0
torque_delay_s = 0.0

[road]
mu = 1.0
# bank_deg = [[0.0, 0.0], [80.0, -9.2], [400.0, -9.2], [480.0, 0.0]]
#                           # road bank (s [m], bank [deg]) along the path, linear between the
#                           # points; > 0 raises the left side (10DoF plant); none: flat
# [[road.patch]]            # a stretch of lower friction along the path
# s_start_m = 500.0
# s_end_m = 600.0
# mu = 0.5

# [[fault]]                 # a measurement that reads NaN for a while
# kind = "nan_measurement"  # or "steer_limit" (value = the limit [rad], no channel)
# channel = "x"
# t_start_s = 10.0
# duration_s = 0.05
'''


@main.group(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree scenario new my_scenario.toml
  flatfree scenario new my_imu.toml --from paper-imu
  flatfree scenario list""")
def scenario() -> None:
    """Scenario files (TOML) and the named scenarios."""


@scenario.command("new", context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree scenario new my_scenario.toml
  flatfree scenario new my_imu.toml --from paper-imu
  flatfree run my_scenario.toml""")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--from", "from_name", metavar="NAME",
              help="Write the named scenario NAME (see `flatfree scenario list`) instead of "
                   "the commented template.")
@click.option("--force", is_flag=True, help="Overwrite FILE if it exists.")
def scenario_new(file: Path, from_name: str | None, force: bool) -> None:
    """Write a scenario to FILE, to edit and run with `flatfree run FILE`.

    Without --from: a template with every key commented, the values of the named scenario
    `paper`. With --from NAME: the named scenario NAME, every key set, without comments
    (keys left at their default of None, such as reference.closed, are omitted: the template
    shows them).
    """
    text = SCENARIO_TEMPLATE
    if from_name is not None:
        sc = _named(from_name)
        head = (f"The named scenario {sc.name!r} of flatfree {__version__} "
                f"(flatfree.scenarios): {sc.description}. Run it with `flatfree run "
                f"{file.name}`; `flatfree scenario new FILE` writes a commented template.")
        text = textwrap.fill(head, width=96, initial_indent="# ", subsequent_indent="# ",
                             break_on_hyphens=False) + "\n\n" + sc.to_toml()
    if file.exists() and not force:
        raise _fail(f"{file} exists; use --force to overwrite it")
    if not file.parent.exists():
        raise _fail(f"folder {file.parent} does not exist")
    try:
        file.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise _fail(f"{file}: cannot write this file ({exc.strerror or exc})") from None
    _err(f"wrote {file}")


@scenario.command("list", context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree scenario list
  flatfree scenario list --json
  flatfree run paper-imu""")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
def scenario_list(as_json: bool) -> None:
    """The named scenarios (flatfree.scenarios), run by `flatfree run NAME`."""
    rows = []
    for name in _scenarios_module().SCENARIO_NAMES:
        sc = _named(name)
        rows.append({"name": name, "controller": sc.controller, "vehicle": sc.vehicle,
                     "reference": sc.reference.track or sc.reference.recording,
                     "noise": sc.noise, "description": sc.description})
    if as_json:
        click.echo(json.dumps({"scenarios": rows}))
        return
    w = max(len(r["name"]) for r in rows)
    click.echo(f"{'name':{w}s}  {'controller':11s} {'vehicle':12s} {'reference':15s} "
               f"{'noise':5s}  description")
    for r in rows:
        click.echo(f"{r['name']:{w}s}  {r['controller']:11s} {r['vehicle']:12s} "
                   f"{r['reference']:15s} {'on' if r['noise'] else 'off':5s}  "
                   f"{r['description']}")


# ------------------------------------------------------------------------------------------
# run
# ------------------------------------------------------------------------------------------
def _vehicle_option(ctx, param, value: str | None) -> str | None:
    if value is None:
        return None
    from flatfree.scenario import _canonical
    from flatfree.vehicles.params import vehicle_file

    try:  # the loader's lookup and message; a path is read at the run
        vehicle_file(value)
    except ValueError as exc:
        raise click.BadParameter(f"{exc}; or the path of a vehicle TOML file") from None
    return _canonical(value, "vehicle")  # a bundled car in its own spelling, as a Scenario


def _controller_choices() -> list[str]:
    from flatfree.scenario import CONTROLLERS

    return list(CONTROLLERS)


def _positive_float(ctx, param, value):
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"{value!r}: must be a finite number > 0")
    return value


#: --control-period of `run` and `demo` (Scenario.with_control_period)
_CONTROL_PERIOD = click.option(
    "--control-period", "control_period_s", type=float, callback=_positive_float, metavar="S",
    help="Run the controller every S seconds, its estimator windows and denoisers rescaled "
         "to keep their durations (tuned at 0.001 s; setting timing.control_dt_s alone keeps "
         "their sample counts).")


def _is_file_spec(spec: str | None) -> bool:
    """Whether ``flatfree run``'s SCENARIO names a file (else a named scenario)."""
    return spec is not None and (Path(spec).is_file() or spec.lower().endswith(".toml"))


def _renamed_for_controller(sc, base, *, named: bool, vehicle: str | None,
                            scales: dict[str, float] | None = None):
    """``sc``, ``base`` with its controller replaced (``--controller``) or its model's
    stiffness scaled (``--cf-scale``, ``--cr-scale``: ``scales``), named and described for
    the controller it runs: as the named scenario it then is, if any (``paper --controller
    flatness`` is ``paper-flatness``, ``paper-flatness --cf-scale 0.3 --cr-scale 0.3`` is
    ``paper-mismatch``), else with the base's description saying what the options changed."""
    if named:
        mod = _scenarios_module()
        # what a named scenario fixes (the options' seed and duration aside)
        keys = [f.name for f in dataclasses.fields(sc)
                if f.name not in ("name", "description", "seed", "timing")]
        for name in mod.SCENARIO_NAMES:
            try:
                other = mod.named_scenario(name, vehicle=vehicle)
            except ValueError:  # (the recorded scenarios take no vehicle)
                continue
            if all(_same_field(other, sc, k) for k in keys):
                return sc.with_(name=other.name, description=other.description)
    parts = []
    if sc.controller != base.controller:
        parts.append(f"the {sc.controller} controller in place of {base.controller} "
                     "(--controller)")
    if scales:
        parts.append("its model's " + ", ".join(f"{k} {v:g}" for k, v in scales.items())
                     + " (" + ", ".join("--" + k.replace("_", "-") for k in scales) + ")")
    what = "; ".join(parts)
    return sc.with_(description=f"{base.description}; {what}" if base.description else what)


def _same_field(a, b, key: str) -> bool:
    """Whether two scenarios agree on ``key``; controller settings that resolve to the same
    settings are the same (``cf_scale = 1`` is the default: ``paper-mismatch --cf-scale 1
    --cr-scale 1`` is ``paper-flatness``)."""
    if key != "controller_settings" or a.controller != b.controller:
        return getattr(a, key) == getattr(b, key)
    from flatfree.controllers.vehicle import settings_from_mapping

    try:
        return (settings_from_mapping(a.controller, a.controller_settings)
                == settings_from_mapping(b.controller, b.controller_settings))
    except ValueError:  # (checked later, where the error names the setting)
        return a.controller_settings == b.controller_settings


def _load_base(spec: str | None, recording: str | None, vehicle: str | None):
    """The scenario a run starts from: a TOML file, a named scenario, or the default. A named
    track scenario takes ``vehicle`` from ``named_scenario(vehicle=...)`` (the car in its
    description, its natural-output tuning)."""
    from flatfree.scenario import load_scenario

    if spec is None:
        spec = "recorded" if recording is not None else "paper"
    elif _is_file_spec(spec):
        try:
            return load_scenario(Path(spec))
        except ValueError as exc:
            raise _fail(str(exc)) from None
    mod = _scenarios_module()
    if spec not in mod.SCENARIO_NAMES:
        raise _fail(f"unknown scenario {spec!r}: give a TOML file, or a named scenario: "
                    f"{', '.join(mod.SCENARIO_NAMES)}")
    if vehicle is not None and not spec.startswith("recorded"):  # the recorded: their own car
        return _named(spec, vehicle=vehicle)
    return _named(spec)


def build_scenario(spec: str | None = None, *, controller: str | None = None,
                   track: str | None = None, recording: str | None = None,
                   vehicle: str | None = None, cf_scale: float | None = None,
                   cr_scale: float | None = None, noise: bool | None = None,
                   seed: int | None = None, duration_s: float | None = None,
                   control_period_s: float | None = None, settings: Sequence[str] = ()):
    """The scenario of ``flatfree run``: the base (file, name or default) with the options.

    ``--controller`` different from the scenario's drops the scenario's controller settings
    (they belong to the other controller; ``mfc-natural`` then takes the car's tuning,
    :func:`flatfree.scenarios.natural_settings`) and names and describes the scenario for the
    controller it runs (:func:`_renamed_for_controller`: ``paper`` with ``flatness`` is
    ``paper-flatness``); ``--cf-scale``/``--cr-scale`` go into the
    controller settings (only the flatness controller takes them: another one refuses them
    when the run starts). ``settings`` (``--set FIELD=VALUE``, repeatable) are applied last,
    in order, by :func:`flatfree.scenario.scenario_with_settings`: a ``--set`` wins over the
    options (``--seed 1 --set seed=2`` runs seed 2). ``control_period_s``
    (``--control-period``) runs the controller at that period with its windows and denoisers
    rescaled to keep their durations (:meth:`~flatfree.scenario.Scenario.with_control_period`),
    before the ``--set`` options. ``noise`` is applied as the setting
    ``noise=true`` / ``noise=false`` (named ``--noise`` / ``--no-noise`` in its errors) before
    them, so that a scenario named ``...-noise-free``
    (which the scenario refuses with the noise on) can take ``--noise --set name=NAME``. A
    bundled car, track or recording comes out in its own spelling (``--track monza``:
    ``Monza``; :class:`~flatfree.scenario.Scenario`). Raises :class:`InputError` (exit 2) on
    bad input.
    """
    from flatfree.scenario import (
        _part_errors,
        _Setting,
        _settings,
        _with_settings,
        scenario_with_settings,
    )
    from flatfree.vehicles.params import bundled_name

    if track is not None and recording is not None:
        raise _fail("give --track or --recording, not both")
    sc = base = _load_base(spec, recording, vehicle)
    try:
        changes: dict[str, Any] = {}
        ctrl_settings = dict(sc.controller_settings)
        if controller is not None and controller != sc.controller:
            changes["controller"] = controller
            ctrl_settings = {}
            if controller == "mfc-natural":  # its tuning is the car's (alpha_lat)
                ctrl_settings = _scenarios_module().natural_settings(
                    sc.vehicle if vehicle is None else vehicle)
        if cf_scale is not None:
            ctrl_settings["cf_scale"] = cf_scale
        if cr_scale is not None:
            ctrl_settings["cr_scale"] = cr_scale
        changes["controller_settings"] = ctrl_settings
        if vehicle is not None:
            # a file's or a recorded scenario's car, with its tuning as below (the description
            # is the file's own); a named track scenario has it already (_load_base): no change
            changes["vehicle"] = vehicle
            natural = _scenarios_module().natural_settings
            if changes.get("controller", sc.controller) == "mfc-natural" and vehicle != sc.vehicle:
                # the peugeot406's earlier settings, as files of the earlier templates hold
                # them: the defaults, {}, before its algebraic tuning (session 21), and that
                # tuning before the curvature term (session 23)
                base_earlier = (bundled_name(sc.vehicle) == "peugeot406"
                                and ctrl_settings in ({}, _PEUGEOT_SESSION21))
                for imu in (False, True):
                    if ctrl_settings == natural(sc.vehicle, imu=imu) or (
                            not imu and base_earlier):
                        # the base's settings are its car's tuning: take the new car's
                        # (alpha_lat), with the same estimator
                        changes["controller_settings"] = natural(vehicle, imu=imu)
        if seed is not None:
            changes["seed"] = seed
        if duration_s is not None:
            changes["timing"] = dataclasses.replace(sc.timing, duration_s=duration_s)
        # --noise as the setting noise=true, named as the option in the messages
        noise_setting = [] if noise is None else [_Setting(
            f"noise={str(noise).lower()}", ("noise",), noise, str(noise).lower(),
            shown="--noise" if noise else "--no-noise")]
        sc = sc.with_(**changes)
        if vehicle is not None:  # its file read now: its error is the option's, not the run's
            for *_, exc in _part_errors(sc, controller=False):
                raise _fail(f"--vehicle: {exc}")
        scales = {k: v for k, v in (("cf_scale", cf_scale), ("cr_scale", cr_scale))
                  if v is not None}
        if "controller" in changes or scales:  # the name and description said the base's
            sc = _renamed_for_controller(sc, base, named=base.name in
                                         _scenarios_module().SCENARIO_NAMES
                                         and not _is_file_spec(spec), vehicle=vehicle,
                                         scales=scales)
        # a new track or a recording, as its setting: the other one and the old file's shape
        # settings go (a --set after this may give them for the new one)
        for key, value in (("reference.track", track), ("reference.recording", recording)):
            if value is not None:
                sc = scenario_with_settings(sc, {key: value})
        if control_period_s is not None:
            sc = sc.with_control_period(control_period_s)
        sc = _with_settings(sc, [*noise_setting, *_settings(settings)])
    except ValueError as exc:
        raise _fail(str(exc)) from None
    return sc


@contextlib.contextmanager
def _collecting(warned: list[str]):
    """The library's warnings of the block appended to ``warned`` as text instead of shown
    (those before an exception too)."""

    with recording() as caught:
        try:
            yield
        finally:
            warned.extend(str(w.message) for w in caught)


def _simulate_collecting(sc, warned: list[str]):
    """simulate(sc) and the reference it ran on, ``(trajectory, reference)`` (built once:
    prepare, then the run), the library's warnings (e.g. a curve beyond the car's steer lock)
    appended to ``warned`` (:func:`_collecting`); a ValueError passes through, the one of a
    run too long for the memory (simulate's RunTooLongError, naming timing.duration_s) saying
    where the run ends at the latest and how to make it longer (:func:`_reference_end`)."""
    from flatfree.simulation import RunTooLongError, prepare, simulate_prepared

    with _collecting(warned):
        prep = prepare(sc)
        try:
            return simulate_prepared(prep), prep.reference
        except RunTooLongError as exc:  # (raised by the run's allocations, not by prepare)
            raise ValueError(f"{exc}; {_reference_end(sc, prep.reference)}") from None


def _reference_end(sc, ref) -> str:
    """Where a run ends at the latest: the end of its reference path, how long its reference
    ``ref`` lasts, and the setting that makes it longer (reference.laps on a closed track)."""
    spec = sc.reference
    lasts = f", {ref.duration:.1f} s"
    if spec.recording is not None:
        return (f"a run ends where its reference ends (the recording {spec.recording}{lasts}), "
                "and no setting makes a recording longer")
    what = (f"{spec.laps} lap{'s' if spec.laps != 1 else ''} of {spec.track}{lasts} at its "
            "speed profile")
    more = ("for a longer run set reference.laps (--set reference.laps=N)"
            if ref.path.closed else "an open path cannot be driven longer")
    return f"a run ends where its reference path ends ({what}); {more}"


def _simulate(sc, warned: list[str]):
    """:func:`_simulate_collecting` (trajectory, reference); a ValueError (bad input,
    unsupported feature) becomes exit code 2, and the library's warnings are printed as one
    line each on stderr, ``warning: ...``, and appended to ``warned`` (an empty list: for the
    run's metrics.json and report)."""
    try:
        out = _simulate_collecting(sc, warned)
    except ValueError as exc:
        raise _fail(f"scenario {sc.name!r} (controller {sc.controller}): {exc}") from None
    for w in warned:
        _err(f"warning: {w}")
    return out


def _time_axis(tr) -> np.ndarray:
    return np.asarray(tr["t_ref"]) if "t_ref" in tr else tr.time


def recorded_steer_of(runs: Sequence, sc, reference=None) -> list[np.ndarray]:
    """The recording's steer [rad] at the samples of each trajectory in ``runs``.

    Read on each run's reference clock (``t_ref`` when logged) through
    :func:`flatfree.scenarios.recorded_steer`, called once for all runs (it builds the
    recording's reference, unless given as ``reference``).
    """
    clocks = [_time_axis(tr) for tr in runs]
    if not clocks:
        return []
    rec = _scenarios_module().recorded_steer(np.concatenate(clocks), sc, reference=reference)
    return np.split(rec, np.cumsum([c.size for c in clocks])[:-1])


def steer_rms_vs_recorded_deg(tr, recorded: np.ndarray, startup_s: float | None = None
                              ) -> float:
    """RMS of (the applied steer - the recorded steer) [deg] after the start-up interval.

    ``recorded``: the recorded steer [rad] at the samples of ``tr``
    (:func:`recorded_steer_of`). Non-finite samples are left out; NaN when none is left.
    """
    from flatfree.metrics import DEFAULT_STARTUP_S

    startup = DEFAULT_STARTUP_S if startup_s is None else startup_s
    keep = tr.time >= tr.time[0] + startup
    d = np.asarray(tr["steer"])[keep] - np.asarray(recorded)[keep]
    d = d[np.isfinite(d)]
    return math.degrees(float(np.sqrt(np.mean(d * d)))) if d.size else math.nan


def _finite_or_none(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with each non-finite float as None (JSON's null: NaN is not JSON), as
    :meth:`flatfree.metrics.Metrics.to_dict` gives the metrics."""
    return {k: None if isinstance(v, float) and not math.isfinite(v) else v
            for k, v in values.items()}


def _number(value: float | None, spec: str = ".3f") -> str:
    """A number for a line of text: ``n/a`` for None or a non-finite one (a metric with no
    sample to measure), as the JSON's null."""
    return "n/a" if value is None or not math.isfinite(value) else format(value, spec)


def _run_json(sc, tr, metrics, extra: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {
        "scenario": sc.name,
        "controller": sc.controller,
        "track": sc.reference.track if sc.reference.track is not None else sc.reference.recording,
        "vehicle": sc.vehicle,
        "plant": sc.plant,
        "noise": sc.noise,
        "seed": sc.seed,
    }
    out.update(metrics.to_dict())
    out["status_time_s"] = tr.status_time
    out.update(_finite_or_none(extra))
    return out


def _xy(ref) -> tuple[np.ndarray, np.ndarray]:
    """The desired path (x, y) of a reference, for the figures."""
    return np.asarray(ref["x"]), np.asarray(ref["y"])


@main.command(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree run                                   the paper's scenario (mfc-natural, Norisring)
  flatfree run --controller mfc-flat --track Monza --json
  flatfree run --controller flatness --cf-scale 0.3 --cr-scale 0.3
  flatfree run my_scenario.toml --seed 2 --out run1      another draw of the sensor noise
  flatfree run paper-mismatch                    a named scenario
  flatfree run --recording LVMS_23_01_04_B --json     adds steer_rms_vs_recorded_deg
  flatfree run --track my_track.csv --duration 30
  flatfree run paper-imu --set reference.j_lat_max=15 --set sensors.y.markov_order=2
  flatfree run paper-imu --control-period 0.01      the controller at 100 Hz
  flatfree run --set controller_settings.alpha_lat=40 --set reference.j_lat_max=15

\b
--set FIELD=VALUE reaches any field of a scenario by its dotted path in the TOML layout of
`flatfree scenario new` (reference.*, timing.*, sensors.CHANNEL.*, actuators.*, road.mu,
road.bank_deg, controller_settings.*, vehicle_overrides.*, seed, ...); VALUE is a TOML value
(15, 1.5e-3, inf, true, "Monza", [1, 2]) or else a bare string (reference.track=Monza). An
inline table given to a table merges its keys into it, each as TABLE.KEY=VALUE, the table's
other fields kept ('reference={j_lat_max = 15, v_max = 40}'). FIELD= (nothing after the =)
puts a field back to its default, and TABLE= a whole table (timing=, sensors.y=: exact;
controller_settings=: the controller's defaults). The --set options are applied after the
other options, so they win. Faults ([[fault]]) and friction patches ([[road.patch]]) are set
whole, as an array of inline tables ('fault=[{kind = "steer_limit", t_start_s = 5,
duration_s = 1, value = 0.01}]'), and cleared with fault= (road.patch=).

""" + _scenario_names_help() + """

\b
Exit codes: 0 completed, 1 the run did not complete (left the track, non-finite state), 2 bad
usage or input.""")
@click.argument("scenario_file", metavar="[SCENARIO]", required=False)
@click.option("--controller", type=click.Choice(_controller_choices(), case_sensitive=False),
              help="Controller (default: the scenario's); a named scenario becomes the one "
                   "that runs it, if any (paper: paper-flatness).")
@click.option("--track", metavar="NAME_OR_CSV",
              help="Bundled track (case-insensitive, see `flatfree tracks`) or a CSV path.")
@click.option("--recording", metavar="NAME_OR_CSV",
              help="Follow a recording's own path, speed and timing (without SCENARIO: "
                   "the recorded scenario, dallara_av21); --json adds "
                   "steer_rms_vs_recorded_deg.")
@click.option("--vehicle", metavar="PRESET", callback=_vehicle_option,
              help="Vehicle preset (see `flatfree vehicles`) or a vehicle TOML path.")
@click.option("--cf-scale", type=float, callback=_positive_float, metavar="X",
              help="Flatness controller: its model's front cornering stiffness x nominal.")
@click.option("--cr-scale", type=float, callback=_positive_float, metavar="X",
              help="Flatness controller: its model's rear cornering stiffness x nominal.")
@click.option("--noise/--no-noise", default=None, help="Sensor noise on or off "
              "(default: the scenario's); as --set noise=true/false before the other --set.")
@click.option("--seed", type=click.IntRange(min=0), help="Seed of the sensor noise.")
@click.option("--duration", "duration_s", type=float, callback=_positive_float, metavar="S",
              help="Stop after S seconds (default: one lap, or the whole recording).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Write scenario.toml, trajectory.parquet, metrics.json, figures and "
                   "report.html into this folder.")
@click.option("--csv", "with_csv", is_flag=True,
              help="With --out: also write trajectory.csv (one header line, 'name [unit]') "
                   "and trajectory.csv.json (status, units, meta).")
@_CONTROL_PERIOD
@click.option("--set", "settings", multiple=True, metavar="FIELD=VALUE",
              help="Set a scenario field by its dotted path, e.g. reference.j_lat_max=15, "
                   "reference.closed=false (a track file's shape; --track and --recording "
                   "drop it), reference.smoothing_length_m=40, sensors.y.markov_order=2, "
                   "controller_settings.alpha_lat=40; an inline table merges its keys "
                   "into a table ('reference={j_lat_max = 15}' keeps the reference's other "
                   "fields); FIELD= (nothing after the =) puts the field, or a whole table "
                   "(timing=), back to its default (repeatable; applied after the other "
                   "options, so it wins over them).")
@click.option("--json", "as_json", is_flag=True,
              help="Print exactly one JSON object (metrics and settings) on stdout.")
def run(scenario_file, controller, track, recording, vehicle, cf_scale, cr_scale, noise, seed,
        duration_s, control_period_s, settings, out_dir, with_csv, as_json) -> None:
    """Run one closed-loop scenario and print its metrics.

    SCENARIO is a TOML file (see `flatfree scenario new`) or a named scenario (listed below);
    without it the paper's scenario (or, with --recording, the recorded one) is the base, and
    the options change it; --set changes any field, last.
    """
    from flatfree.metrics import compute_metrics
    from flatfree.report import RunResult, format_table

    if with_csv and out_dir is None:
        raise _fail("--csv writes into the --out folder: give --out DIR too")
    if controller is not None:
        controller = controller.lower()
    sc = build_scenario(scenario_file, controller=controller, track=track,
                        recording=recording, vehicle=vehicle, cf_scale=cf_scale,
                        cr_scale=cr_scale, noise=noise, seed=seed, duration_s=duration_s,
                        control_period_s=control_period_s, settings=settings)
    if (noise or seed is not None) and not sc.effective_sensors.random:
        given = [o for o, v in (("--noise", noise), ("--seed", seed is not None)) if v]
        verb = "has" if len(given) == 1 else "have"
        why = (f"scenario {sc.name!r} gives no sensor random noise (a noise_std or a "
               "markov_std)" if sc.noise else "the run's sensor noise is off")
        _err(f"note: {' and '.join(given)} {verb} no effect: {why}")
    with _out_dir(out_dir):
        # the reference the run was built on, for the notes, the recorded steer and the figures
        warned: list[str] = []
        tr, reference = _simulate(sc, warned)
        notes = _note_short_or_capped(sc, tr, reference)
        with _collecting([]):  # its one warning (every metric NaN) is this command's own note
            m = compute_metrics(tr, startup_s=sc.timing.startup_s)
        extra: dict[str, float] = {}
        rec = None
        if sc.reference.recording is not None:
            (rec,) = recorded_steer_of([tr], sc, reference)
            extra["steer_rms_vs_recorded_deg"] = steer_rms_vs_recorded_deg(
                tr, rec, sc.timing.startup_s)
        result = RunResult(label=sc.controller, scenario=sc, trajectory=tr, metrics=m,
                           extra=extra)
        payload = _run_json(sc, tr, m, extra)
        if warned:  # what the run warned about goes with its numbers (stderr is not kept)
            payload["warnings"] = warned
        if notes:  # and what explains them (a run shorter than asked, every metric null)
            payload["notes"] = notes
        if out_dir is not None:
            _write_run(out_dir, result, payload, reference, rec)
            if with_csv:
                tr.to_csv(out_dir / "trajectory.csv")
    if as_json:
        click.echo(json.dumps(_round_times(payload)))
    else:
        where = sc.reference.track or sc.reference.recording
        if not sc.noise:
            noise_txt = "noise off"
        elif sc.sensors.random:
            noise_txt = f"noise on, seed {sc.seed}"
        else:
            noise_txt = "noise on but no sensor has random noise"
        click.echo(f"{sc.name}: {sc.controller} on {where}, {sc.vehicle}, {sc.plant} plant, "
                   f"{noise_txt}")
        click.echo(format_table([result]))
        for k, v in extra.items():
            click.echo(f"{k}: {_number(v)}")
        if tr.status_time is not None:
            click.echo(f"the run stopped at t = {tr.status_time:.2f} s: {tr.status.value}")
        if out_dir is not None:
            click.echo(f"wrote {out_dir}/: report.html, scenario.toml, metrics.json, "
                       f"trajectory.parquet{', trajectory.csv (+ .json)' if with_csv else ''}"
                       ", figures/ (files of the same names replaced)")
    if not tr.completed:
        sys.exit(1)


def _note_short_or_capped(sc, tr, reference) -> list[str]:
    """Notes on stderr when the run's length explains its results: it ended at the end of the
    reference path before the requested duration, or within the start-up interval that the
    metrics leave out (every metric then null). ``reference``: the run's reference. Returns
    the notes (for the run's JSON)."""
    from flatfree.metrics import no_sample_after_startup

    notes = []
    t = tr.time
    requested = sc.timing.duration_s
    if (tr.completed and requested is not None and t.size
            and t[-1] + sc.timing.log_dt_s < requested - 1e-9):
        notes.append(f"the run ended at {t[-1]:.2f} s, not at the requested duration of "
                     f"{requested:g} s (timing.duration_s): {_reference_end(sc, reference)}")
    startup = sc.timing.startup_s
    if no_sample_after_startup(tr, startup):
        end = f"its log ends at {t[-1]:.2f} s" if t.size else "it logged nothing"
        notes.append(f"every metric is null: {end}, within the start-up interval of "
                     f"timing.startup_s = {startup:g} s that the metrics leave out; run "
                     "longer (--duration) or shorten it (--set timing.startup_s=S)")
    for n in notes:
        _err(f"note: {n}")
    return notes


def _write_run(out_dir: Path, result, payload: dict[str, Any], reference,
               recorded: np.ndarray | None = None) -> None:
    """Write a run's scenario, trajectory, metrics, figures and report into ``out_dir`` (made
    by :func:`_out_dir`); ``reference``: the run's reference (the desired path)."""
    from flatfree.report import write_report

    sc, tr = result.scenario, result.trajectory
    sc.save(out_dir / "scenario.toml")
    tr.to_parquet(out_dir / "trajectory.parquet")
    (out_dir / "metrics.json").write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    runs = {sc.controller: tr}
    ref_xy = _xy(reference)
    figs = []
    # the recorded steer at each logged sample (read at the run's reference time), drawn on
    # the run's clock like the run's own steer: the pairs that steer_rms_vs_recorded_deg uses
    rec = None if recorded is None else (tr.time, recorded)
    for stem, caption, draw in _run_figures(runs, ref_xy, rec):
        figs.append((caption, _draw(out_dir / "figures", stem, draw)))
    write_report(out_dir / "report.html", [result], figs,
                 title=f"flatfree run: {sc.name}, {sc.controller}",
                 notes=[*(f"warning: {w}" for w in payload.get("warnings", [])),
                        *(f"note: {n}" for n in payload.get("notes", []))])


def _draw(folder: Path, stem: str, draw: Callable) -> Path:
    """Draw with ``draw() -> (fig, axes)`` and save PNG and SVG; return the PNG path."""
    from flatfree import plotting as pl

    fig, _ = draw()
    return pl.save_figure(fig, folder, stem)[0]


def _run_figures(runs, ref_xy, recorded_steer=None):
    """(stem, caption, draw) of the figures of a set of runs on one reference."""
    from flatfree import plotting as pl

    def paths():
        fig, ax = pl.new_figure(7.5, 6.0)
        pl.plot_paths(ax[0, 0], runs, reference=ref_xy)
        return fig, ax

    def errors():
        fig, ax = pl.new_figure(8.0, 6.0, nrows=2)
        pl.plot_lateral_error(ax[0, 0], runs)
        pl.plot_yaw_error(ax[1, 0], runs)
        return fig, ax

    def inputs():
        fig, ax = pl.new_figure(8.0, 6.0, nrows=2)
        pl.plot_torque(ax[0, 0], runs)
        pl.plot_steer(ax[1, 0], runs, reference=recorded_steer)
        return fig, ax

    def f_est():
        fig, ax = pl.new_figure(8.0, 6.0, nrows=2)
        pl.plot_f_estimate(ax[0, 0], runs, loop="lon")
        pl.plot_f_estimate(ax[1, 0], runs, loop="lat")
        return fig, ax

    def worst(k: str) -> tuple[bool, float]:  # completed runs first, then the smallest error
        e = np.abs(np.asarray(runs[k]["lateral_error"])) if "lateral_error" in runs[k] else []
        e = e[np.isfinite(e)] if len(e) else e
        return (not runs[k].completed, float(np.max(e)) if len(e) else math.inf)

    best = min(runs, key=worst)

    def track_map():
        fig, ax = pl.new_figure(7.5, 6.0)
        pl.plot_track_map(ax[0, 0], runs[best], reference=ref_xy)
        ax[0, 0].set_title(f"track map, |lateral error| ({best})")
        return fig, ax

    return [
        ("fig4_paths", "Desired and actual paths, zoom on the worst corner (paper Fig. 4).",
         paths),
        ("fig5_errors", "Lateral and yaw errors over time (paper Fig. 5).", errors),
        ("fig6_inputs", "Wheel torque and steer (paper Fig. 6)"
         + (" against the recorded steer." if recorded_steer is not None else "."), inputs),
        ("f_estimates", "Estimated F of the model-free loops over time.", f_est),
        ("track_map", f"Track map coloured by the lateral error ({best}).", track_map),
    ]


# ------------------------------------------------------------------------------------------
# demo
# ------------------------------------------------------------------------------------------
def _try_run(label: str, sc, warned: list[str]):
    """``(RunResult, reference)``: the run and the reference it ran on, or why it could not be
    made (a ValueError of the engine) and None; the library's warnings of the run are appended
    to ``warned``."""
    from flatfree.metrics import compute_metrics
    from flatfree.report import RunResult

    try:
        tr, ref = _simulate_collecting(sc, warned)
    except ValueError as exc:
        return RunResult(label=label, scenario=sc, error=str(exc)), None
    with _collecting(warned):
        m = compute_metrics(tr, startup_s=sc.timing.startup_s)
    return RunResult(label=label, scenario=sc, trajectory=tr, metrics=m), ref


#: Fields ``demo --set`` refuses: they differ between the demo's runs (names, three
#: controllers and their settings, two cars, a track and a recording), so one value for all
#: makes no sense.
DEMO_FIXED_FIELDS = ("name", "description", "controller", "controller_settings", "vehicle",
                     "vehicle_overrides", "reference.track", "reference.recording")


def _demo_tasks(*, track: str | None, seed: int, duration_s: float | None,
                rec_duration_s: float | None, no_recorded: bool, noise: bool,
                control_period_s: float | None = None,
                settings: Sequence[str] = ()) -> list[tuple[str, str, Any]]:
    """The demo's runs as (group, label, scenario), each changed by ``control_period_s``
    (``--control-period``: :meth:`~flatfree.scenario.Scenario.with_control_period`) and then
    by ``settings`` (``--set``).

    Raises :class:`InputError` (exit 2) on a bad setting or one of
    :data:`DEMO_FIXED_FIELDS`.
    """
    from flatfree.scenario import NOISE_FREE_SUFFIX, _changed_paths, scenario_with_settings

    for s in settings:
        try:
            paths = _changed_paths(s)  # an inline table's keys (reference={track = "Monza"})
        except ValueError as exc:
            raise _fail(str(exc)) from None
        # the field, a part of it, or a table holding it (reference=: all of it)
        fixed = next((f for f in DEMO_FIXED_FIELDS for path in paths if path == f
                      or path.startswith(f + ".") or f.startswith(path + ".")), None)
        if fixed is not None:
            raise _fail(f"--set {s}: demo runs several controllers, cars and references, so "
                        f"{fixed} cannot be set for all of them; use `flatfree run` (or demo "
                        "--track for the track)")
    sfx = "" if noise else NOISE_FREE_SUFFIX
    kw: dict[str, Any] = {"seed": seed, "duration_s": duration_s}
    if track is not None:
        kw["track"] = track
    tasks: list[tuple[str, str, Any]] = []  # (group, label, scenario)
    for ctrl, name in PAPER_RUNS:
        tasks.append(("paper", ctrl, _named(name + sfx, **kw)))
    tasks.append(("paper", IMU_LABEL, _named("paper-imu" + sfx, **kw)))
    tasks.append(("mismatch", "flatness, 0.3 Cf, 0.3 Cr", _named("paper-mismatch" + sfx, **kw)))
    if not no_recorded:
        rec = _named("recorded" + sfx, seed=seed, duration_s=rec_duration_s)
        for ctrl in ("mfc-flat", "mfc-natural"):
            tasks.append(("recorded", ctrl, rec.with_(controller=ctrl, controller_settings={})
                          if ctrl != rec.controller else rec))
        tasks.append(("recorded", IMU_LABEL,
                      _named("recorded-imu" + sfx, seed=seed, duration_s=rec_duration_s)))
    if not settings and control_period_s is None:
        return tasks
    out = []
    for group, label, base in tasks:
        try:
            sc = base if control_period_s is None else base.with_control_period(control_period_s)
            out.append((group, label, scenario_with_settings(sc, list(settings))))
        except ValueError as exc:
            raise _fail(f"{group}, {label}: {exc}") from None
    return out


@main.command(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree demo                              writes flatfree-out/report.html
  flatfree demo --out /tmp/paper --no-noise
  flatfree demo --track Monza
  flatfree demo --track Norisring --duration 20 --recording-duration 20   a quick look
  flatfree demo --control-period 0.002 --set actuators.steer_tau_s=0.05

\b
--set FIELD=VALUE (as in `flatfree run`) changes every run of the demo, after the other
options; the fields that differ between its runs (name, description, controller,
controller_settings, vehicle, vehicle_overrides, reference.track, reference.recording) are
refused.

\b
Exit codes: 0 every run was made (a run that leaves the track is a result, shown in the
table), 2 bad input, or a controller the closed loop does not provide yet (the report is
still written, with the reason).""")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              default=DEFAULT_OUT, show_default=True, help="Folder of the report and figures.")
@click.option("--track", metavar="NAME_OR_CSV", default=None,
              help="Track of the paper scenarios (default: the scenarios' default track).")
@click.option("--duration", "duration_s", type=float, callback=_positive_float, metavar="S",
              help="Stop each track run after S seconds (default: one lap).")
@click.option("--recording-duration", "rec_duration_s", type=float, callback=_positive_float,
              metavar="S", help="Stop each recorded run after S seconds (default: all of it).")
@click.option("--no-recorded", is_flag=True, help="Skip the recorded-reference runs (Fig. 6).")
@click.option("--noise/--no-noise", default=True, show_default=True, help="Sensor noise.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the sensor noise.")
@_CONTROL_PERIOD
@click.option("--set", "settings", multiple=True, metavar="FIELD=VALUE",
              help="Set a scenario field of every run, e.g. actuators.steer_tau_s=0.05 "
                   "(repeatable; applied after the other options).")
@click.option("--progress/--no-progress", default=None,
              help="Progress bar on stderr (default: when stderr is a terminal).")
def demo(out_dir: Path, track, duration_s, rec_duration_s, no_recorded, noise, seed,
         control_period_s, settings, progress) -> None:
    """Reproduce the paper: its three controllers, figures 2-6, a table, an HTML report.

    Runs the paper's scenarios (the peugeot406 on the 10DoF model, noisy sensors) with the
    flatness-based controller, model-free control on flat outputs and on natural outputs,
    the flatness controller with 0.3 Cf, 0.3 Cr (Fig. 2), a braking-in-a-turn maneuver
    (Fig. 3), and the model-free controllers on the recorded Las Vegas drive (Fig. 6); beside
    them, beyond the paper, the natural-output controller with its lateral F from the inertial
    unit (paper-imu, recorded-imu); prints our errors beside the paper's and writes
    OUT/report.html (self-contained) and OUT/figures/*.png, *.svg.
    """
    from flatfree.simulation import reference_of

    tasks = _demo_tasks(track=track, seed=seed, duration_s=duration_s,
                        rec_duration_s=rec_duration_s, no_recorded=no_recorded, noise=noise,
                        control_period_s=control_period_s, settings=settings)
    # the desired path (and a check of the track name before the long part)
    try:
        ref_xy = _xy(reference_of(tasks[0][2]))
    except ValueError as exc:
        raise _fail(str(exc)) from None
    with _out_dir(out_dir):  # before the long part too
        missing = _demo_runs(out_dir, tasks, ref_xy, settings, progress)
    if missing:
        _err("not every paper run could be made: "
             + "; ".join(f"{r.label}: {r.error}" for r in missing))
        sys.exit(2)


def _demo_runs(out_dir: Path, tasks, ref_xy, settings: Sequence[str], progress) -> list:
    """The long part of ``demo``: its runs, figures, report and table; returns the paper runs
    that could not be made."""
    from tqdm import tqdm

    from flatfree import plotting as pl
    from flatfree.report import format_table, write_report

    show = sys.stderr.isatty() if progress is None else progress
    results: dict[str, list] = {"paper": [], "mismatch": [], "recorded": []}
    t0 = time.perf_counter()
    bar = tqdm(total=len(tasks) + 2, disable=not show, file=sys.stderr, unit="step",
               desc="flatfree demo")
    warned: list[str] = []
    rec_ref = None  # the recorded runs' reference (they share the recording), as built by one
    for group, label, sc in tasks:
        bar.set_postfix_str(f"{group}: {label}")
        task_warned: list[str] = []
        result, ref = _try_run(label, sc, task_warned)
        results[group].append(result)
        if group == "recorded" and ref is not None:
            rec_ref = ref
        warned.extend(f"{group}, {label}: {w}" for w in task_warned)
        bar.update()
    ran = [r for r in results["recorded"] if r.trajectory is not None]
    rec_steer = dict(zip([r.label for r in ran], recorded_steer_of(
        [r.trajectory for r in ran], ran[0].scenario, rec_ref) if ran else [], strict=True))
    results["recorded"] = [
        dataclasses.replace(r, extra={"steer_rms_vs_recorded_deg": steer_rms_vs_recorded_deg(
            r.trajectory, rec_steer[r.label], r.scenario.timing.startup_s)})
        if r.label in rec_steer else r for r in results["recorded"]]
    bar.set_postfix_str("braking in a turn (Fig. 3)")
    fig3 = pl.braking_in_turn("peugeot406")
    bar.update()
    bar.set_postfix_str("figures")
    figdir = out_dir / "figures"
    paper_runs = {r.label: r.trajectory for r in results["paper"] if r.trajectory is not None}
    figs: list[tuple[str, Path]] = []
    notes: list[str] = []
    if settings:
        notes.append("every run changed from the paper's scenarios by --set "
                     + ", --set ".join(settings))
    # Figure 2: flatness nominal vs mismatch
    # the paper group has one flatness run (PAPER_RUNS): the nominal curve
    flat_nominal = next((r.trajectory for r in results["paper"]
                         if r.scenario.controller == "flatness" and r.trajectory is not None),
                        None)
    mism = {**({"nominal Cf, Cr": flat_nominal} if flat_nominal is not None else {}),
            **{r.label: r.trajectory for r in results["mismatch"] if r.trajectory is not None}}
    if mism:
        def fig2():
            fig, ax = pl.new_figure(8.0, 6.0, nrows=2)
            pl.plot_mismatch(ax[0, 0], mism, signal="lateral_error")
            pl.plot_mismatch(ax[1, 0], mism, signal="yaw_error")
            return fig, ax
        figs.append((("Flatness-based control with nominal and 0.3 Cf, 0.3 Cr cornering "
                      "stiffness (paper Fig. 2)."), _draw(figdir, "fig2_mismatch", fig2)))
    else:
        notes.append("Figure 2 (flatness control with mismatched stiffness) is missing: "
                     + "; ".join(r.error or "" for r in results["mismatch"]))

    def fig3_draw():
        fig, ax = pl.new_figure(8.0, 4.5)
        pl.plot_cornering_stiffness(ax[0, 0], fig3)
        return fig, ax
    figs.append((("Effective cornering stiffness Fy/alpha of each axle, braking at 5 m/s^2 in "
                  "a 4 m/s^2 turn at 20 m/s, 10DoF peugeot406 (paper Fig. 3)."),
                 _draw(figdir, "fig3_cornering_stiffness", fig3_draw)))
    if paper_runs:
        # the track runs' inputs figure is not the paper's Fig. 6 (that one is the recording's)
        renamed = {"fig6_inputs": ("inputs_track", "Wheel torque and steer on the track runs.")}
        for stem, caption, draw in _run_figures(paper_runs, ref_xy):
            name, text = renamed.get(stem, (stem, caption))
            figs.append((text, _draw(figdir, name, draw)))
    rec_runs = {r.label: r.trajectory for r in results["recorded"] if r.trajectory is not None}
    if rec_runs:
        first = next(iter(rec_runs))
        rec_ref = (rec_runs[first].time, rec_steer[first])  # as in _write_run

        def fig6():
            fig, ax = pl.new_figure(8.0, 6.0, nrows=2)
            pl.plot_torque(ax[0, 0], rec_runs)
            pl.plot_steer(ax[1, 0], rec_runs, reference=rec_ref)
            return fig, ax
        figs.append((("Wheel torque and steer of the model-free controllers against the "
                      "recorded steer, dallara_av21 on the LVMS recording (paper Fig. 6; the "
                      "recording has no wheel torque)."), _draw(figdir, "fig6_inputs", fig6)))
    bar.update()
    bar.close()
    missing = [r for r in results["paper"] + results["mismatch"] if r.error is not None]
    for r in missing:
        notes.append(f"{r.label}: not run: {r.error}")
    for w in dict.fromkeys(warned):  # in order, once each
        _err(f"warning: {w}")
        notes.append(f"warning: {w}")
    scen = {f"{g}: {r.label}": r.scenario for g in results for r in results[g]}
    report = write_report(out_dir / "report.html", results["paper"], figs, scenarios=scen,
                          notes=notes,
                          extra_tables={k: v for k, v in (
                              ("Flatness control with 0.3 Cf, 0.3 Cr (paper Fig. 2)",
                               results["mismatch"]),
                              ("Recorded reference: dallara_av21 on the LVMS recording",
                               results["recorded"])) if v})
    # the controller too: the recorded mfc-flat run is the "recorded" scenario's, controller
    # replaced (its name alone said mfc-natural)
    summary = {g: [{"label": r.label, "scenario": r.scenario.name,
                    "controller": r.scenario.controller,
                    **({"error": r.error} if r.error else r.metrics.to_dict()),
                    **_finite_or_none(dict(r.extra))} for r in rs]
               for g, rs in results.items()}
    (out_dir / "metrics.json").write_text(json.dumps(summary, indent=2, default=str) + "\n",
                                          encoding="utf-8")
    click.echo(format_table(results["paper"]))
    for r in results["recorded"]:
        if r.metrics is not None:
            click.echo(f"recorded, {r.label}: max lateral error "
                       f"{_number(100 * r.metrics.lateral_error_max_m, '.2f')} cm, steer RMS "
                       f"vs recorded {_number(r.extra.get('steer_rms_vs_recorded_deg'))} deg "
                       f"({r.metrics.status})")
    click.echo(f"wrote {report} and {len(figs)} figures in {figdir} "
               f"({time.perf_counter() - t0:.1f} s)")
    return missing


# ------------------------------------------------------------------------------------------
# bench
# ------------------------------------------------------------------------------------------
def _best(fn: Callable[[], Any], repeats: int) -> float:
    return best_time(fn, repeats=repeats)


def _bench_results(quick: bool) -> dict[str, Any]:
    from flatfree.controllers.intelligent import IntelligentParams, make_state
    from flatfree.models.bicycle3dof import Bicycle3DoFParams
    from flatfree.models.bicycle3dof import simulate as sim3
    from flatfree.models.tendof import TenDoF
    from flatfree.vehicles import load_vehicle

    repeats = 2 if quick else 5
    sim_s = 2.0 if quick else 10.0
    dt = 1e-3
    n = int(round(sim_s / dt))
    vp = load_vehicle("peugeot406")
    out: dict[str, Any] = {}
    # open loop, 10DoF
    model = TenDoF(vp)
    x0 = model.initial_state(20.0)
    u = model.inputs(300.0, 0.02, n=n)
    model.simulate(x0, u[:2], dt)  # compile or load the cache
    w = _best(lambda: model.simulate(x0, u, dt), repeats)
    out["open_loop_10dof_real_time_factor"] = sim_s / w
    # open loop, 3DoF (the paper's design model)
    bp = Bicycle3DoFParams.from_vehicle(vp)
    u3 = np.column_stack([np.full(n, 300.0), np.full(n, 0.02)])
    x3 = np.array([20.0, 0.0, 0.0])
    sim3(bp, x3, u3[:2], dt)
    w = _best(lambda: sim3(bp, x3, u3, dt), repeats)
    out["open_loop_3dof_real_time_factor"] = sim_s / w
    # one intelligent controller step (iPD with its F estimator), compiled loop
    p = IntelligentParams(nu=2, alpha=60.0, dt=dt, window=50, kp=16.0, kd=8.0).to_array()
    s = make_state(p)
    n_c = 20_000 if quick else 200_000
    _ctrl_loop(p, s, 10)
    w = _best(lambda: _ctrl_loop(p, s, n_c), repeats)
    out["controller_step_ns"] = 1e9 * w / n_c
    # closed loop, each paper controller (10DoF, 1 kHz, noise)
    from flatfree.simulation import simulate

    for ctrl, name in PAPER_RUNS:
        sc = _named(name, duration_s=5.0 if quick else 20.0)
        try:
            simulate(sc.with_(timing=dataclasses.replace(sc.timing, duration_s=0.01)))
            rtf = max(float(simulate(sc).meta.get("real_time_factor", math.nan))
                      for _ in range(2 if quick else 3))
        except ValueError as exc:
            out[f"closed_loop_{ctrl}_real_time_factor"] = None
            out.setdefault("notes", []).append(f"{ctrl}: {exc}")
            continue
        out[f"closed_loop_{ctrl}_real_time_factor"] = rtf
    # what `flatfree run` costs on the default track: reference, controller and the loop
    if not quick:
        sc = _named("paper")
        t0 = time.perf_counter()
        tr = simulate(sc)
        out["paper_run_wall_s"] = time.perf_counter() - t0
        out["paper_run_simulated_s"] = tr.duration
    return out


def _ctrl_loop(p, s, n):
    return _ctrl_loop_kernel()(p, s, n, 1e-3)


@functools.lru_cache(maxsize=1)
def _ctrl_loop_kernel():
    """A compiled loop: an iPD steering a damped mass (so the data change every step)."""
    from numba import njit

    from flatfree.controllers.intelligent import intelligent_reset, intelligent_step

    @njit(cache=False)
    def kernel(p, s, n, dt):
        intelligent_reset(p, s)
        y = 0.0
        v = 0.0
        acc = 0.0
        for k in range(n):
            r = math.sin(0.5 * k * dt)
            u = intelligent_step(p, s, y, r, 0.5 * math.cos(0.5 * k * dt),
                                 -0.25 * math.sin(0.5 * k * dt))
            y += dt * v  # a damped mass y'' = -0.5 y' + 60 u
            v += dt * (-0.5 * v + 60.0 * u)
            acc += abs(y - r)
        return acc

    return kernel


@main.command(context_settings=CONTEXT, epilog="""\b
Examples:
  flatfree bench
  flatfree bench --json --quick

Timings are the best of several repeats, after compilation; on a shared or busy machine they
vary, so compare orders of magnitude.""")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--quick", is_flag=True, help="Shorter runs and fewer repeats (a rough check).")
def bench(as_json: bool, quick: bool) -> None:
    """Speed of the library on this machine: open and closed loop, controller step."""
    from flatfree.report import machine_info

    res = _bench_results(quick)
    res["machine"] = machine_info()
    if as_json:
        click.echo(json.dumps(res))
        return
    labels = {
        "open_loop_10dof_real_time_factor": ("10DoF model, open loop, RK4 1 ms", "x real time"),
        "open_loop_3dof_real_time_factor": ("3DoF model, open loop, RK4 1 ms", "x real time"),
        "controller_step_ns": ("iPD step with its F estimator (window 50)", "ns"),
    }
    for ctrl, _ in PAPER_RUNS:
        labels[f"closed_loop_{ctrl}_real_time_factor"] = (
            f"closed loop {ctrl}, 10DoF at 1 kHz, noise", "x real time")
    labels["paper_run_wall_s"] = ("paper scenario, one lap: simulate() wall time", "s")
    labels["paper_run_simulated_s"] = ("  simulated (a lap, or until the run failed)", "s")
    for k, (text, unit) in labels.items():
        if k not in res:
            continue
        v = res[k]
        click.echo(f"{text:48s} {'n/a' if v is None else f'{v:12.1f}'} {unit}")
    for note in res.get("notes", []):
        click.echo(f"note: {note}")
    mi = res["machine"]
    click.echo(f"machine: {mi['cpu']}, {mi['cores']} cores, python {mi['python']}, "
               f"numba {mi['numba']}, {mi['date (UTC)']} UTC")


if __name__ == "__main__":  # pragma: no cover
    main(prog_name="flatfree")
