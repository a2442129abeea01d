"""Steer-rate and speed-error figures the README quotes (issue 7; one seed, no timing).

Run as a script (``python benchmarks/effort_figures.py [--track Norisring] [--seed 0]``): the
named scenarios ``paper`` and ``paper-imu``, with and without noise, and ``paper`` on the
drivable speed profile (``reference.drive_limit = true``), one lap each; prints the max lateral
error, the steer-rate RMS and the speed-error RMS (flatfree.metrics definitions); then the
steer command's jitter (its change per 1 ms step, 20 s) of ``paper`` with its own settings and
with the controller's defaults, noisy and noise-free. Nothing here
is a test. The figures are benchmarks/README.md "Closed loop", "Efforts and the speed error".
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from flatfree.metrics import compute_metrics
from flatfree.scenarios import DEFAULT_TRACK, named_scenario
from flatfree.simulation import simulate

CASES = (("paper", ()), ("paper-noise-free", ()), ("paper-imu", ()),
         ("paper-imu-noise-free", ()), ("paper", ("reference.drive_limit=true",)))
# the steer command's sample-to-sample change over 20 s logged at every 1 ms control step
JITTER = ("timing.log_dt_s=0.001", "timing.duration_s=20")


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
    print("steer command jitter, RMS of its change per 1 ms control step after 1 s, first 20 s "
          "[rad] (noisy / noise-free)")
    # `paper` with its own settings (scenarios.NATURAL_SETTINGS) and with the controller's
    # defaults (no settings over them)
    for label, defaults in (("paper", False), ("paper, the controller's defaults", True)):
        rms = []
        for name in ("paper", "paper-noise-free"):
            sc = named_scenario(name, track=args.track, seed=args.seed).with_settings(JITTER)
            if defaults:
                sc = sc.with_(controller_settings={})
            tr = simulate(sc)
            cmd = tr["steer_cmd"][tr.time > sc.timing.startup_s]
            rms.append(float(np.sqrt(np.mean(np.diff(cmd) ** 2))))
        print(f"  {label:34s} {rms[0]:.5f} / {rms[1]:.6f}")


if __name__ == "__main__":
    main()
