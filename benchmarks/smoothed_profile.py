"""Would a longitudinal jerk limit keep the algebraic design on Spa? (issue 7)

Run as a script::

    python benchmarks/smoothed_profile.py                  # Spa, seeds 0-9, windows 1, 21, 41
    python benchmarks/smoothed_profile.py --seeds 20 --windows 1,11,21 --track Spa

The default speed profile switches from full drive (+3 m/s^2) to full braking (-6 m/s^2) from
one node to the next (no longitudinal jerk limit; ``flatfree.tracks.speed``), and the earlier
notes named such a limit as the next thing to try against the algebraic ``paper`` design's
departures on Spa (with the controller's defaults, session 12: Eau Rouge ~30-32 s, the chicane
~42-45 s; with session 21's settings mostly the chicane, 42.5-48 s, benchmarks/README.md
"Three log sections re-run with session 21's settings"). Before building one into the
profile this script asks whether it would help, with a stand-in: every profile the reference
builds is replaced by a morphological *opening* of its speed, a minimum filter over ``W``
nodes followed by a moving average over the same ``W`` nodes (both wrapping round a closed
track). The result is nowhere faster than the friction-ellipse profile (each point's average
window only holds minima of windows that contain the point; the script also takes the
pointwise minimum to be exact about it), and its acceleration ramps over about ``W`` metres
instead of one node, so its longitudinal jerk is bounded (the table prints the largest jerk
between segments, ``|a_(i+1) - a_i| / dt`` with ``dt`` the node's time step). ``W = 1`` is the
default profile.

The stand-in is installed by patching ``flatfree.tracks.reference.speed_profile`` for the
duration of the run (a benchmark's experiment, not an API). Nothing here is a test; the
figures are in benchmarks/README.md "Closed loop", "A smoothed speed profile".
"""

from __future__ import annotations

import argparse
import contextlib
import platform
import time

import numpy as np
from scipy.ndimage import minimum_filter1d, uniform_filter1d

import flatfree.tracks.reference as reference_module
from flatfree.metrics import compute_metrics
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate
from flatfree.tracks.speed import SpeedProfile


def opened(profile: SpeedProfile, window: int) -> SpeedProfile:
    """The profile's speed opened over ``window`` nodes (module docstring); ``window`` 1 gives
    the profile back unchanged."""
    if window <= 1:
        return profile
    mode = "wrap" if profile.track.closed else "nearest"
    v = uniform_filter1d(minimum_filter1d(profile.v, window, mode=mode), window, mode=mode)
    v = np.minimum(v, profile.v)
    ds = np.diff(profile.s)
    a = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * ds)
    t = np.concatenate([[0.0], np.cumsum(2.0 * ds / (v[1:] + v[:-1]))])
    return SpeedProfile(track=profile.track, s=profile.s, v=v, a=a, t=t,
                        limits=profile.limits, vehicle=profile.vehicle)


def max_jerk(profile: SpeedProfile) -> float:
    """Largest jump of the segment acceleration between neighbouring segments per unit time at
    their common node [m/s^3] (the node's time step: the mean of the two segments')."""
    dt = np.diff(profile.t)
    return float(np.max(np.abs(np.diff(profile.a)) / (0.5 * (dt[1:] + dt[:-1]))))


@contextlib.contextmanager
def opened_profiles(window: int, seen: list[SpeedProfile]):
    """Every speed profile built by the references within the block is :func:`opened`."""
    original = reference_module.speed_profile

    def patched(*args, **kwargs):
        prof = opened(original(*args, **kwargs), window)
        seen.append(prof)
        return prof

    reference_module.speed_profile = patched
    try:
        yield
    finally:
        reference_module.speed_profile = original


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--track", default="Spa")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--windows", default="1,21,41", help="comma-separated W [nodes]")
    ap.add_argument("--scenario", default="paper")
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"{args.scenario} on {args.track}, seeds 0-{args.seeds - 1}")
    print("| W [nodes] | lap [s] | max jerk [m/s^3] | max |a| [m/s^2] | completed "
          "| left (seed at time) | max lateral of completed laps [cm] |")
    print("|---:|---:|---:|---:|---:|---|---:|")
    for window in (int(w) for w in args.windows.split(",")):
        seen: list[SpeedProfile] = []
        left, lateral = [], []
        with opened_profiles(window, seen):
            for seed in range(args.seeds):
                tr = simulate(named_scenario(args.scenario, track=args.track, seed=seed))
                if tr.status.value == "completed":
                    lateral.append(100.0 * compute_metrics(tr).lateral_error_max_m)
                else:
                    left.append(f"{seed} at {tr.status_time:.1f} s")
        prof = seen[0]
        span = f"{min(lateral):.2f}-{max(lateral):.2f}" if lateral else "-"
        print(f"| {window} | {prof.t[-1]:.2f} | {max_jerk(prof):.1f} | "
              f"{np.max(np.abs(prof.a)):.2f} | {len(lateral)}/{args.seeds} | "
              f"{', '.join(left) or '-'} | {span} |")


if __name__ == "__main__":
    main()
