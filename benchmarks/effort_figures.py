"""Steer-rate and speed-error figures the README quotes (issue 7; one seed, no timing).

Run as a script (``python benchmarks/effort_figures.py [--track Norisring] [--seed 0]``): the
named scenarios ``paper`` and ``paper-imu``, with and without noise, and ``paper`` on the
drivable speed profile (``reference.drive_limit = true``), one lap each; prints the max lateral
error, the steer-rate RMS and the speed-error RMS (flatfree.metrics definitions). Nothing here
is a test. The figures are benchmarks/README.md "Closed loop", "Efforts and the speed error".
"""

from __future__ import annotations

import argparse
import warnings

from flatfree.metrics import compute_metrics
from flatfree.scenarios import DEFAULT_TRACK, named_scenario
from flatfree.simulation import simulate

CASES = (("paper", ()), ("paper-noise-free", ()), ("paper-imu", ()),
         ("paper-imu-noise-free", ()), ("paper", ("reference.drive_limit=true",)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--track", default=DEFAULT_TRACK)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"{'scenario':22s} {'settings':28s} {'status':10s} {'lat max [cm]':>12s} "
          f"{'steer-rate RMS [rad/s]':>22s} {'speed err RMS [m/s]':>19s}")
    for name, settings in CASES:
        sc = named_scenario(name, track=args.track, seed=args.seed).with_settings(settings)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tr = simulate(sc)
        m = compute_metrics(tr, startup_s=sc.timing.startup_s)
        print(f"{name:22s} {' '.join(settings) or '-':28s} {m.status:10s} "
              f"{100 * m.lateral_error_max_m:12.2f} {m.steer_rate_rms_radps:22.3f} "
              f"{m.speed_error_rms_mps:19.3f}")


if __name__ == "__main__":
    main()
