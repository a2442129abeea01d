"""What a GNSS/INS position's slow error does to the true lateral error (issue 7).

Run as a script::

    python benchmarks/rtk_drift.py                       # Norisring and Spa, seeds 0-4
    python benchmarks/rtk_drift.py --tracks Norisring --seeds 10 --tau 10,60 --std 0.01
    python benchmarks/rtk_drift.py --order 2             # a smooth (second-order) drift

The named scenarios' position noise (:data:`flatfree.scenarios.REALISTIC_SENSORS`) is 1 mm of
white jitter per 1 kHz sample: an RTK-GNSS/INS datasheet's "1 cm" accuracy is mostly a *slow*
error, which those scenarios leave out (scenarios module docstring). This script adds it to the
x and y channels as the sensors' first-order Gauss-Markov drift (``SensorChannel.markov_std``,
``markov_tau_s``; per axis, stationary std ``--std``, correlation time ``--tau``), on top of the
white jitter, and reports for ``paper`` and ``paper-imu`` the max true lateral error (the
metric), the max of the drift across the path (what a controller that tracked the measured
position perfectly would show as true error), and the max lateral error seen by the controller
(measured pose against the path), over the lap after the metrics' start-up.

Nothing here is a test; the figures are in benchmarks/README.md "Closed loop", "A slow
position error".
"""

from __future__ import annotations

import argparse
import platform
import time
import warnings

import numpy as np

from flatfree.metrics import DEFAULT_STARTUP_S, compute_metrics
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate


def _with_drift(sc, std: float, tau: float, order: int = 1):
    return sc.with_settings({f"sensors.{k}.{f}": v for k in ("x", "y") for f, v in (
        ("markov_std", std), ("markov_tau_s", tau), ("markov_order", order))})


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tracks", default="Norisring,Spa")
    ap.add_argument("--scenarios", default="paper-imu,paper")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--std", type=float, default=0.01, help="drift std per axis [m]")
    ap.add_argument("--tau", default="10,60", help="correlation times [s]")
    ap.add_argument("--order", type=int, default=1, choices=(1, 2),
                    help="Gauss-Markov order (2: smooth at short time scales, like an INS "
                         "blend; sensors module docstring)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"position drift per axis: std {args.std * 100:.1f} cm, Gauss-Markov order "
          f"{args.order}, white jitter as named")
    print("max over the lap after the start-up [cm]: the position error across the path (every "
          "run); over the completed runs, the true lateral error (per seed) and the one the "
          "controller sees (measured pose)")
    for track in args.tracks.split(","):
        for name in args.scenarios.split(","):
            for tau in [None, *(float(v) for v in args.tau.split(","))]:
                true_max, meas_max, across, left = [], [], [], []
                for seed in range(args.seeds):
                    sc = named_scenario(name, track=track, seed=seed)
                    if tau is not None:
                        sc = _with_drift(sc, args.std, tau, args.order)
                    tr = simulate(sc)
                    m = compute_metrics(tr)
                    after = tr.time >= tr.time[0] + DEFAULT_STARTUP_S
                    # the measured pose's deviation minus the true one: the position error
                    # across the path; the controller sees lateral_error + that
                    err = (tr["meas_e_y"] - tr["e_y"])[after]
                    across.append(float(np.max(np.abs(err))))
                    if m.status != "completed":
                        left.append(f"seed {seed} {m.status} at {tr.status_time:.1f} s")
                        continue
                    true_max.append(m.lateral_error_max_m)
                    meas_max.append(float(np.max(np.abs(tr["lateral_error"][after] + err))))
                lab = "none" if tau is None else f"{tau:g} s"
                am = np.array(across) * 100
                line = (f"{track:10s} {name:10s} {lab:>6s}  {len(true_max)}/{args.seeds}   "
                        f"across {am.min():5.2f}-{am.max():5.2f}")
                if true_max:
                    tm, mm = (np.array(v) * 100 for v in (true_max, meas_max))
                    line += (f"  true {tm.min():5.2f}-{tm.max():5.2f} "
                             f"({' '.join(f'{v:.2f}' for v in tm)})  seen {mm.min():5.2f}-"
                             f"{mm.max():5.2f}")
                if left:
                    line += "  [" + "; ".join(left) + "]"
                print(line, flush=True)


if __name__ == "__main__":
    main()
