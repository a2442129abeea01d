"""The model-free controllers at other control periods: sample counts kept or rescaled.

Run as a script (``python benchmarks/control_period.py [--seeds N] [--tracks A,B] [--designs
paper,...] [--rates 1000,...] [--set KEY=VALUE]``); it prints
the table of benchmarks/README.md "Control period". For each design (``paper``, ``paper-imu``,
``paper-mfc-flat``) and control rate (1000 / 500 / 200 / 100 Hz), the named scenario with

- ``timing.control_dt_s`` alone changed: the sample counts (estimator windows, denoisers) of
  the 1 kHz tuning kept, so their durations grow with the period (what ``--set
  timing.control_dt_s=...`` gave before the rescaling existed; the run now warns);
- :meth:`flatfree.scenario.Scenario.with_control_period`: the counts rescaled to keep their
  durations (:func:`flatfree.controllers.vehicle.rescale_sample_counts`).

Each cell: the worst max lateral error [cm] over the completed seeds, the number completed,
the steer-rate RMS [rad/s] of seed 0, and when the others left the track. The sensors sample
at the control rate with the scenario's noise per sample (1 mm of position noise per sample
at every rate). Nothing here is a test (tests/test_imu_estimator.py holds a 100 Hz lap,
tests/test_control_period.py the warning).
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

from sweep_seeds import parse_settings  # benchmarks/ is the script's folder (sys.path[0])

from flatfree.metrics import compute_metrics
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate

RATES_HZ = (1000, 500, 200, 100)
DESIGNS = ("paper", "paper-imu", "paper-mfc-flat")


def run(name: str, track: str, seed: int, hz: int, rescaled: bool, settings: dict):
    sc = named_scenario(name, track=track, seed=seed)
    if settings:
        sc = sc.with_(controller_settings={**sc.controller_settings, **settings})
    dt = 1.0 / hz
    if rescaled:
        sc = sc.with_control_period(dt)
    else:
        sc = sc.with_(timing=dataclasses.replace(sc.timing, control_dt_s=dt))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the kept counts' warning is this table's point
        tr = simulate(sc)
        return compute_metrics(tr), tr.status_time


def cell(name: str, track: str, seeds: int, hz: int, rescaled: bool, settings: dict) -> str:
    runs = [run(name, track, s, hz, rescaled, settings) for s in range(seeds)]
    done = [m for m, _ in runs if m.status == "completed"]
    left = [t for m, t in runs if m.status != "completed"]
    worst = f"{100 * max(m.lateral_error_max_m for m in done):6.2f}" if done else "     -"
    out = f"{worst} {len(done)}/{seeds} {runs[0][0].steer_rate_rms_radps:.2f}"
    return out + (f" (left {min(left):.1f}-{max(left):.1f} s)" if left else "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--tracks", default="Norisring,Spa")
    ap.add_argument("--designs", default=",".join(DESIGNS))
    ap.add_argument("--rates", default=",".join(map(str, RATES_HZ)), help="control rates [Hz]")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="controller setting over the scenario's (repeatable)")
    args = ap.parse_args()
    settings = parse_settings(args.set)
    tracks = args.tracks.split(",")
    print(f"max lateral [cm] over completed seeds, completed/{args.seeds}, steer-rate RMS "
          "[rad/s] of seed 0")
    print(f"{'design':15s} {'rate':>7s}  " + "  ".join(
        f"{t + ' ' + v:44s}" for t in tracks for v in ("counts kept", "rescaled")))
    for name in args.designs.split(","):
        for hz in map(int, args.rates.split(",")):
            cells = [cell(name, t, args.seeds, hz, r, settings) for t in tracks
                     for r in (False, True)]
            print(f"{name:15s} {hz:4d} Hz  " + "  ".join(f"{c:44s}" for c in cells),
                  flush=True)


if __name__ == "__main__":
    main()
