"""The paper's three vehicle controllers on the 10DoF plant with realistic noise (issue 7).

Runs the named scenarios ``paper``, ``paper-flatness``, ``paper-mfc-flat`` and
``paper-mismatch`` on the default track, prints their metrics, and plots the lateral errors
(``paper_scenarios.png`` next to this script). ``paper-flatness``, ``paper-mfc-flat`` and
``paper-mismatch`` run with the outer path-following correction (default on; controllers/
vehicle.py): they complete the lap. Usage::

    python examples/paper_scenarios.py [track]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from flatfree.metrics import compute_metrics
from flatfree.scenarios import paper_scenarios
from flatfree.simulation import simulate


def main(track: str | None = None) -> None:
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for name, sc in paper_scenarios(track=track).items():
        tr = simulate(sc)
        m = compute_metrics(tr)
        print(f"{name:16s} {m.status:10s} after {tr.duration:6.1f} s: max |e_y| "
              f"{100 * m.lateral_error_max_m:8.2f} cm, RMS {100 * m.lateral_error_rms_m:7.2f} cm, "
              f"max |yaw error| {m.yaw_error_max_deg:6.2f} deg, steer rate RMS "
              f"{m.steer_rate_rms_radps:.3f} rad/s")
        axes[0].plot(tr.time, 100 * tr["lateral_error"], label=name, lw=0.8)
        axes[1].plot(tr.time, tr["steer"], label=name, lw=0.8)
    # symlog: the natural-output design stays within 3 cm, the flat-output one within ~1 m
    axes[0].set_yscale("symlog", linthresh=2.0)
    axes[0].set_ylabel("lateral error [cm] (symlog)")
    axes[1].set_ylabel("steer [rad]")
    axes[1].set_xlabel("time [s]")
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"10DoF peugeot406, {track or 'default track'}, realistic sensors")
    out = Path(__file__).with_name("paper_scenarios.png")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
