"""The speed-loop window trade and the flat-output designs' singular speed (issue 7, session 4).

Run as a script::

    python benchmarks/session4_checks.py                 # both sections, ~1 minute
    python benchmarks/session4_checks.py --only window

Sections (benchmarks/README.md "Speed-loop window" and "The flat-output designs' singular
speed"):

``window``
    ``MfcNaturalSettings.window_lon`` 50 / 75 / 100 / 150 / 200 samples, seed 0: the recorded
    drive (``recorded``: torque RMS, torque-rate RMS, speed-error RMS) and its noise-free torque
    RMS; the dallara_av21 on LVMS (``paper`` and ``paper-imu`` with the dallara's settings, as
    in tests/paper_scenario_bounds.json): speed-error RMS, torque-rate RMS, max lateral error.
``flat``
    The recording with ``mfc-flat`` and ``flatness`` (with and without noise): max lateral
    error before and after the recorded car brakes through the singular speed v*, the speed
    where the steer first exceeds 3 deg late in the run, and where a run left the path; the
    steady ratio G = d y2 / d r (proportional to the steer's authority on y2'') at the
    recording's start speed against 30 m/s.

Nothing here is a test (the singular speed's formula is: tests/test_paper_scenarios.py).
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

from flatfree.controllers.flatness import singular_speed
from flatfree.controllers.vehicle import y2_per_r
from flatfree.metrics import compute_metrics
from flatfree.models.bicycle3dof import Bicycle3DoFParams
from flatfree.scenarios import named_scenario, natural_settings
from flatfree.simulation import prepare, simulate
from flatfree.vehicles import load_vehicle

_WINDOWS = (50, 75, 100, 150, 200)


def _with(sc, **settings):
    return sc.with_(controller_settings={**sc.controller_settings, **settings})


def window() -> None:
    print("window_lon | recorded: torque RMS [N m], torque rate RMS [kN m/s], speed RMS [m/s] "
          "| dallara on LVMS, paper / paper-imu: speed RMS [m/s], torque rate [kN m/s], "
          "max lateral [cm]")
    for w in _WINDOWS:
        m = compute_metrics(simulate(_with(named_scenario("recorded"), window_lon=w)))
        cells = [(f"{m.torque_rms_nm:5.0f} {m.torque_rate_rms_nmps / 1e3:5.1f} "
                 f"{m.speed_error_rms_mps:.3f}")]
        for imu in (False, True):
            sc = named_scenario("paper-imu" if imu else "paper", track="LVMS").with_(
                vehicle="dallara_av21")
            sc = sc.with_(controller_settings={**natural_settings("dallara_av21", imu=imu),
                                               "window_lon": w})
            d = compute_metrics(simulate(sc))
            cells.append(f"{d.speed_error_rms_mps:.4f} {d.torque_rate_rms_nmps / 1e3:5.1f} "
                         f"{100 * d.lateral_error_max_m:.2f}")
        print(f"{w:4d} | " + " | ".join(cells), flush=True)
    clean = compute_metrics(simulate(named_scenario("recorded-noise-free")))
    print(f"recorded noise-free (default window): torque RMS {clean.torque_rms_nm:.0f} N m")


def flat() -> None:
    car = load_vehicle("dallara_av21")
    b = Bicycle3DoFParams.from_vehicle(car)
    v_star = singular_speed(b)
    print(f"dallara_av21: yaw index {b.iz / (b.m * b.lf * b.lr):.2f}, v* = {v_star:.2f} m/s")
    for name in ("recorded", "recorded-noise-free"):
        for controller in ("mfc-flat", "flatness"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the singular-speed warning: the point here
                tr = simulate(named_scenario(name).with_(controller=controller,
                                                         controller_settings={}))
            t, vx = tr.time, tr["vx"]
            e = np.abs(tr["lateral_error"])
            line = f"{name:20s} {controller:9s} {tr.status.value}"
            if tr.status_time is not None:
                line += f" at {tr.status_time:.2f} s"
            below = np.nonzero(vx < v_star)[0]  # the final stop
            if below.size:
                t_cross = t[below[0]]
                before = (t > 1.0) & (t < t_cross)
                line += (f"  max lateral {100 * e[before].max():.2f} cm until {t_cross:.1f} s "
                         f"(v < v*), {100 * e[t > 1.0].max():.2f} cm overall")
            big = np.nonzero((np.abs(tr["steer"]) > math.radians(3.0)) & (t > 0.5 * t[-1]))[0]
            if big.size:
                line += f"; |steer| > 3 deg from {t[big[0]]:.2f} s at {vx[big[0]]:.1f} m/s"
            print(line, flush=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        v0 = float(prepare(named_scenario("recorded")).reference["vx"][0])
    g0, g30 = (float(y2_per_r(b, v)) for v in (v0, 30.0))
    print(f"G(v) = d y2/d r at the start {v0:.1f} m/s: {g0:.0f}, at 30 m/s: {g30:.0f} "
          f"(ratio {g30 / g0:.1f}; d y2''/d delta = Cf Cr L G / (m Iz v): "
          f"authority ratio {(g30 / 30.0) / (g0 / v0):.1f})")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="window,flat", help="comma-separated sections")
    args = ap.parse_args(argv)
    for section in args.only.split(","):
        print(f"== {section}")
        {"window": window, "flat": flat}[section]()


if __name__ == "__main__":
    main()
