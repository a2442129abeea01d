"""The speed profile's lateral-jerk limit (``SpeedLimits.j_lat_max``): what it costs, what it
neglects, and what it does in the closed loop (issue 7).

Run as a script::

    python benchmarks/jerk_limit.py                       # parts 0-5 and 7
    python benchmarks/jerk_limit.py --skip 4 --spa-seeds 30   # and the Spa sweep of `paper`

0. the order of magnitude behind ``J_LAT_HANDLING``: the linear 3DoF peugeot406's mean delay
   -G'(0) / G(0) of its steer-to-a_y transfer function G, and the lateral jerk its steer-rate
   limit allows in steady cornering, rate / (L / v^2 + K_us);
1. every bundled track (and LVMS smoothed at 20 m, rougher than bundled): the friction-only
   lap time, the default profile's largest steady lateral jerk v^3 |dkappa/ds| at the nodes,
   and what each limit adds to the lap, friction-only and within the peugeot406's drive limit;
2. what the cap neglects (tracks/speed.py docstring, "Lateral-jerk limit"): on the profile's
   segments the neglected term 2 vbar a kbar against its friction-ellipse bound
   a_x,max a_y,max vbar / v_min^2, the neglected term where the steady one is within 10 % of
   the limit, the steady term's overshoot between nodes, and a centred difference of the node
   curvatures against the track's analytic dkappa/ds;
3. the closed loop on LVMS smoothed at 20 m, a full lap, with and without the limit;
4. the largest limit with which each noise-free design completes the first 10 s there;
5. the closed loop on the bundled tracks with and without the limit;
6. (``--spa-seeds N``) `paper` on Spa, seeds 0..N-1, with and without the limit;
7. the references above ``simulation.ROUGH_JERK`` that set it (Norisring's race line, LVMS
   smoothed at 20 m with and without its start's bridge): the largest steady lateral jerk,
   where, and the noise-free natural-output designs' laps without and with the limit 15.

Nothing here is a test; the figures are in benchmarks/README.md, "Lateral-jerk limit".
"""

from __future__ import annotations

import argparse
import math
import platform
import tempfile
import time
import warnings

import numpy as np
from yaw_feasibility import write_smoothed

from flatfree.actuators import ActuatorParams
from flatfree.metrics import compute_metrics
from flatfree.models.bicycle3dof import Bicycle3DoFParams
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate
from flatfree.tracks import J_LAT_HANDLING, SpeedLimits, load_track, speed_profile, track_names
from flatfree.vehicles import load_vehicle

LIMITS = (20.0, 15.0, 10.0, 5.0)


def _with_limit(sc, j: float):
    return sc.with_settings({"reference.j_lat_max": j})


def _order_of_magnitude() -> None:
    veh = load_vehicle("peugeot406")
    b = Bicycle3DoFParams.from_vehicle(veh)
    big_l, k_us = b.wheelbase, b.understeer_gradient  # K_us [rad / (m/s^2)]
    rate = ActuatorParams.from_vehicle(veh).max_steer_rate
    print("0. peugeot406, linear 3DoF (C_f / C_r = "
          f"{b.cf:,.0f} / {b.cr:,.0f} N/rad): mean delay of a_y behind the steer; the lateral "
          f"jerk of the steer-rate limit ({rate:g} rad/s) in steady cornering")
    for v in (20.0, 30.0):
        a = np.array([[-(b.cf + b.cr) / (b.m * v), (b.cr * b.lr - b.cf * b.lf) / (b.m * v * v) - 1],
                      [(b.cr * b.lr - b.cf * b.lf) / b.iz,
                       -(b.cf * b.lf**2 + b.cr * b.lr**2) / (b.iz * v)]])
        bb = np.array([b.cf / (b.m * v), b.cf * b.lf / b.iz])
        c = v * (a[0] + np.array([0.0, 1.0]))  # a_y = V (beta' + r)
        d = v * bb[0]
        ainv = np.linalg.inv(a)
        g0 = -c @ ainv @ bb + d
        g1 = -c @ ainv @ ainv @ bb
        print(f"  {v:g} m/s: mean delay {-g1 / g0:.3f} s, steer-rate jerk "
              f"{rate / (big_l / v**2 + k_us):.0f} m/s^3", flush=True)


def _profiles(tracks: dict) -> None:
    veh = load_vehicle("peugeot406")
    print("1. lap time [s] of the friction-only profile, its max v^3 |dkappa/ds| [m/s^3], and "
          "the lap time each limit adds [s] (friction only / within the peugeot406's drive "
          "limit)")
    print(f"{'track':22s} {'lap':>8s} {'max jerk':>9s} " + " ".join(
        f"{'j=' + format(j, 'g'):>15s}" for j in LIMITS))
    for label, tk in tracks.items():
        base = speed_profile(tk)
        base_v = speed_profile(tk, vehicle=veh)
        peak = float(np.max(base.v**3 * np.abs(tk.dkappa_ds)))
        cells = []
        for j in LIMITS:
            lim = SpeedLimits(j_lat_max=j)
            d = speed_profile(tk, lim).duration - base.duration
            dv = speed_profile(tk, lim, vehicle=veh).duration - base_v.duration
            cells.append(f"{d:7.3f}/{dv:7.3f}")
        print(f"{label:22s} {base.duration:8.2f} {peak:9.1f} " + " ".join(cells), flush=True)


def _neglected(tracks: dict) -> None:
    print("\n2. the neglected term 2 vbar a kbar on the segments [m/s^3]: its max, the largest "
          "share of its ellipse bound a_x,max a_y,max vbar / v_min^2, its max where the steady "
          "term is >= 0.9 j; the steady term's max / j (between nodes); the centred difference "
          "of the node curvatures against dkappa/ds, max |difference| / max |dkappa/ds|")
    for j in (J_LAT_HANDLING, 5.0):
        print(f"j = {j:g} m/s^3")
        for label, tk in tracks.items():
            lim = SpeedLimits(j_lat_max=j)
            prof = speed_profile(tk, lim)
            v, u, k = prof.v, prof.v**2, tk.kappa
            vbar, ubar = 0.5 * (v[1:] + v[:-1]), 0.5 * (u[1:] + u[:-1])
            kbar = 0.5 * (k[1:] + k[:-1])
            neglected = np.abs(2.0 * vbar * prof.a * kbar)
            steady = np.abs(ubar * vbar * np.diff(k) / tk.ds)
            vmin = np.minimum(v[1:], v[:-1])
            bound = max(lim.ax_drive, lim.ax_brake) * lim.ay * vbar / vmin**2
            near = steady >= 0.9 * j
            dk = tk.dkappa_ds
            centred = np.gradient(k, tk.ds) if not tk.closed else (
                (np.roll(k[:-1], -1) - np.roll(k[:-1], 1)) / (2.0 * tk.ds))
            cd = float(np.max(np.abs(centred[1:-1] - dk[1:centred.size - 1]))
                       / np.max(np.abs(dk)))
            share = np.max(neglected / bound)
            print(f"  {label:22s} max {neglected.max():5.2f}  share {share:6.1%}"
                  f"  near the limit {neglected[near].max() if near.any() else math.nan:5.2f}"
                  f"  steady/j {steady.max() / j:6.4f}  centred {cd:6.2%}", flush=True)


def _closed(label: str, sc, j: float) -> str:
    tr = simulate(_with_limit(sc, j))
    m = compute_metrics(tr)
    left = "" if m.status == "completed" else f" at {tr.status_time:.1f} s"
    return (f"{label:34s} j={j:>4g}: {m.status}{left}, lateral max "
            f"{100 * m.lateral_error_max_m:.2f} cm, yaw max {m.yaw_error_max_deg:.2f} deg "
            f"(RMS {m.yaw_error_rms_deg:.3f}), course max {m.course_error_max_deg:.2f} deg")


def _rough(rough: str, seeds: int) -> None:
    print("\n3. LVMS smoothed at 20 m, a lap")
    for name in ("paper-noise-free", "paper-imu-noise-free"):
        for j in (math.inf, J_LAT_HANDLING):
            print("  " + _closed(name, named_scenario(name, track=rough), j), flush=True)
    for name in ("paper-imu", "paper"):
        for seed in range(seeds):
            sc = named_scenario(name, track=rough, seed=seed)
            for j in (math.inf, J_LAT_HANDLING):
                print("  " + _closed(f"{name} seed {seed}", sc, j), flush=True)


def _thresholds(rough: str) -> None:
    print("\n4. the first 10 s of LVMS smoothed at 20 m, noise-free: the limits [m/s^3] with which "
          "the run completes")
    for name in ("paper-noise-free", "paper-imu-noise-free"):
        sc = named_scenario(name, track=rough, duration_s=10.0)
        ok = [j for j in range(8, 31) if simulate(_with_limit(sc, float(j))).completed]
        print(f"  {name:22s} completes with {ok}", flush=True)


def _bundled(tracks: list[str]) -> None:
    print("\n5. the bundled tracks, a lap (noise-free on every track; seed 0 on Norisring and Spa)")
    for track in tracks:
        cases = [("paper-imu-noise-free", 0)]
        if track in ("Norisring", "Spa"):
            cases += [("paper-imu", 0), ("paper", 0)]
        for name, seed in cases:
            sc = named_scenario(name, track=track, seed=seed)
            for j in (math.inf, J_LAT_HANDLING):
                print("  " + _closed(f"{name} {track}", sc, j), flush=True)


def _spa_sweep(seeds: int) -> None:
    print(f"\n6. paper on Spa, seeds 0-{seeds - 1}")
    for j in (math.inf, J_LAT_HANDLING):
        done, lat, left = 0, [], []
        for seed in range(seeds):
            tr = simulate(_with_limit(named_scenario("paper", track="Spa", seed=seed), j))
            m = compute_metrics(tr)
            if m.status == "completed":
                done += 1
                lat.append(100 * m.lateral_error_max_m)
            else:
                left.append(f"{seed} ({tr.status_time:.1f} s)")
        span = f"{min(lat):.2f}-{max(lat):.2f} cm" if lat else "none completed"
        print(f"  j={j:g}: completed {done}/{seeds}, lateral max {span}; "
              f"left: {', '.join(left) or 'none'}", flush=True)


def _above_rough(rough: str) -> None:
    from flatfree.simulation import ROUGH_JERK, _steady_jerk_peak, reference_of

    print(f"\n7. the references above ROUGH_JERK = {ROUGH_JERK:g} m/s^3: the largest v^3 "
          "|dkappa/ds| and where; the noise-free natural-output designs, a lap")
    cases = (("Norisring race line", None, ["reference.line=raceline"]),
             ("LVMS at 20 m, unbridged", rough, []),
             ("LVMS at 20 m, bridged", "LVMS", ["reference.smoothing_length_m=20"]))
    for label, track, settings in cases:
        # the warning's own figure, of the reference both designs share
        ref = reference_of(named_scenario("paper-noise-free", track=track).with_settings(
            settings))
        jerk, i = _steady_jerk_peak(ref)
        print(f"  {label}: {jerk:.1f} m/s^3 at s = {float(ref['s'][i]):.0f} m "
              f"({float(ref['vx'][i]):.1f} m/s)")
        for name in ("paper-noise-free", "paper-imu-noise-free"):
            sc = named_scenario(name, track=track).with_settings(settings)
            for j in (math.inf, J_LAT_HANDLING):
                print("    " + _closed(name, sc, j), flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip", default="", help="parts to skip, e.g. 3,4")
    ap.add_argument("--rough-seeds", type=int, default=3,
                    help="noisy seeds on the rough LVMS (part 3, default 3)")
    ap.add_argument("--spa-seeds", type=int, default=0, help="part 6's seeds (default 0: skip)")
    args = ap.parse_args(argv)
    skip = set(args.skip.split(","))
    warnings.simplefilter("ignore")
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    with tempfile.TemporaryDirectory() as folder:
        rough = write_smoothed("LVMS", 20.0, folder)
        # each track loaded once for parts 1 and 2
        tracks = {t: load_track(t) for t in track_names()}
        tracks["LVMS smoothed at 20 m"] = load_track(rough)
        if "0" not in skip:
            _order_of_magnitude()
        if "1" not in skip:
            _profiles(tracks)
        if "2" not in skip:
            _neglected(tracks)
        if "3" not in skip:
            _rough(rough, args.rough_seeds)
        if "4" not in skip:
            _thresholds(rough)
        if "7" not in skip:
            _above_rough(rough)
    if "5" not in skip:
        _bundled(track_names())
    if args.spa_seeds > 0:
        _spa_sweep(args.spa_seeds)


if __name__ == "__main__":
    main()
