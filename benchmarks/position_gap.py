"""A gap in the position measurement: how the natural-output designs ride it out (issue 7).

Run as a script (``python benchmarks/position_gap.py [--trace] [--seeds N]``); it prints the
figures of benchmarks/README.md "A held steer held the yaw damper's term twice":

1. the table: Norisring, seed 0, ``paper`` and ``paper-imu``, the position channel ``y`` NaN
   (a ``nan_measurement`` fault) for 0.05 / 0.1 / 0.2 s from 11, 12 and 13 s; max lateral error
   after the 1 s start-up of a 25 s run, or when the car left the track;
2. ``--seeds N``: the 0.1 s gap at 12 s over seeds 0..N-1 (16 s runs);
3. ``--trace``: ``paper`` with the 0.1 s gap at 11 s and without it (16 s runs), per interval
   the max |e_y|, the range of the steer command, of the applied steer and of the lateral
   loop's F_hat, and the share of the logged samples at the steer-rate limit;
4. ``--sweep [--track T] [--channel C]``: gaps of 0.05-0.5 s in ``y`` (or C) starting at 3.0,
   4.3, ... 39.4 s (29 starts,
   each run going on 5 s after its gap's start; seed 0), ``paper`` and ``paper-imu``: per
   duration how many runs stay within 4 cm (2x the target), the median max lateral error and
   the worst of those within (benchmarks/README.md "Bridging a gap in the position").

Nothing here is a test (tests/test_simulation.py holds the 0.1 s gap at 12 s).
"""

from __future__ import annotations

import argparse
import itertools
import warnings

import numpy as np

from flatfree.actuators import ActuatorParams
from flatfree.metrics import compute_metrics
from flatfree.scenario import Fault
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate
from flatfree.vehicles import load_vehicle


def run(name: str, t0: float, dur: float, *, seed: int = 0, duration_s: float = 25.0):
    gap = Fault(kind="nan_measurement", channel="y", t_start_s=t0, duration_s=dur)
    tr = simulate(named_scenario(name, duration_s=duration_s, seed=seed).with_(faults=(gap,)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the start-up warning cannot arise: runs of >= 16 s
        m = compute_metrics(tr)
    return tr, m


def run_settings(settings: dict, t0: float, dur: float, *, seed: int = 0,
                 duration_s: float = 25.0):
    """:func:`run` of ``paper`` with ``settings`` over the controller's defaults instead of
    ``paper``'s own (``benchmarks/tune_natural.py robust``)."""
    gap = Fault(kind="nan_measurement", channel="y", t_start_s=t0, duration_s=dur)
    sc = named_scenario("paper", duration_s=duration_s, seed=seed)
    tr = simulate(sc.with_(faults=(gap,), controller_settings=dict(settings)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = compute_metrics(tr)
    return tr, m


def _result(tr, m) -> str:
    if m.status == "completed":
        return f"{100 * m.lateral_error_max_m:.2f} cm"
    return f"left at {tr.status_time:.1f} s"


def sweep(track: str, channel: str = "y") -> None:
    """Part 4 (module docstring); ``channel`` the one blanked."""
    starts = np.arange(3.0, 40.0, 1.3)
    for name in ("paper", "paper-imu"):
        for dur in (0.05, 0.1, 0.2, 0.3, 0.5):
            res = []
            for t0 in starts:
                gap = Fault(kind="nan_measurement", channel=channel, t_start_s=float(t0),
                            duration_s=dur)
                sc = named_scenario(name, track=track, duration_s=float(t0) + 5.0, seed=0)
                tr = simulate(sc.with_(faults=(gap,)))
                m = compute_metrics(tr)
                res.append(m.lateral_error_max_m if m.status == "completed" else np.inf)
            res = np.array(res)
            ok = res < 0.04
            worst = f"{100 * res[ok].max():.1f} cm" if ok.any() else "-"
            print(f"{track} {channel} {name:10s} {dur:4.2f} s: within 4 cm "
                  f"{ok.sum():2d}/{res.size}, median {100 * np.median(res):.1f} cm, "
                  f"worst within {worst}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trace", action="store_true", help="the 11 s gap's trace (paper)")
    ap.add_argument("--seeds", type=int, default=0, help="the 12 s gap over seeds 0..N-1")
    ap.add_argument("--sweep", action="store_true", help="gaps of 0.05-0.5 s at 29 starts")
    ap.add_argument("--track", default="Norisring", help="the track of --sweep")
    ap.add_argument("--channel", default="y", help="the channel --sweep blanks (default y)")
    args = ap.parse_args()
    if args.sweep:
        sweep(args.track, args.channel)
        return
    print("gap [s] at [s]   paper            paper-imu")
    for t0 in (11.0, 12.0, 13.0):
        for dur in (0.05, 0.1, 0.2):
            cells = [_result(*run(name, t0, dur)) for name in ("paper", "paper-imu")]
            print(f"{dur:4.2f}    {t0:4.1f}    {cells[0]:16s} {cells[1]}")
    if args.seeds:
        for name in ("paper", "paper-imu"):
            cells = [_result(*run(name, 12.0, 0.1, seed=s, duration_s=16.0))
                     for s in range(args.seeds)]
            print(f"{name}, 0.1 s at 12 s, seeds 0-{args.seeds - 1}: {', '.join(cells)}")
    if args.trace:
        rate_max = ActuatorParams.from_vehicle(load_vehicle("peugeot406")).max_steer_rate
        for label, dur in (("0.1 s gap at 11 s", 0.1), ("no gap (the same run)", 0.0)):
            tr = run("paper", 11.0, dur, duration_s=16.0)[0] if dur else simulate(
                named_scenario("paper", duration_s=16.0))
            t = tr.time
            # the applied steer's rate between logged samples, as a share of the actuator's
            at_limit = np.abs(np.diff(tr["steer"], prepend=tr["steer"][0])) / np.diff(
                t, prepend=t[0] - (t[1] - t[0])) >= 0.99 * rate_max
            print(f"paper, {label}: interval, max |e_y|, steer command, applied steer, F_hat "
                  "of the lateral loop, share of the interval at the steer-rate limit")
            edges = (10.9, 11.0, 11.1, 11.2, 11.5, 12.0, 13.0, 14.0, 15.0)
            for a, b in itertools.pairwise(edges):
                w = (t >= a) & (t < b)
                if not w.any():
                    break
                print(f"  {a:5.1f}-{b:4.1f} s  {100 * np.abs(tr['e_y'][w]).max():7.2f} cm  "
                      f"{tr['steer_cmd'][w].min():+.4f}..{tr['steer_cmd'][w].max():+.4f} rad  "
                      f"{tr['steer'][w].min():+.4f}..{tr['steer'][w].max():+.4f} rad  "
                      f"{tr['f_lat'][w].min():+6.2f}..{tr['f_lat'][w].max():+6.2f} m/s^2  "
                      f"{100 * at_limit[w].mean():3.0f} %")
            print(f"  status {tr.status.value} at {tr.status_time} s")


if __name__ == "__main__":
    main()
