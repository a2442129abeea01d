"""Model-free iP versus a classic PI when the plant's input gain changes (issue 6).

The plant, unknown to both controllers, is a first-order system with quadratic drag,

    y' = -a y|y| + b(t) u(t - d),

(a speed loop, for instance) whose input gain b jumps at t = 4 s to 0.3 b_nom or to 3 b_nom, with
an input delay d of 0, 1 or 2 samples. Both controllers are designed for the same 5 rad/s:

* the iP (paper eq. (ip), NOTES.md signs): ultra-local model y' = F + alpha u, Kp = 5 /s,
  alpha = 2 b_nom (top of the gain's range: see the note below), F by the paper's algebraic
  estimator over 10 samples;
* a classic PI tuned on the nominal plant linearised at y = 1 (double closed-loop pole at -5).

The script prints the worst tracking error of both on every run and writes the figure
``intelligent_vs_pid.png`` next to itself (the runs with a 2-sample delay). The same runs are
checked in ``tests/test_intelligent.py``.

Note: with alpha = b_nom instead, the iP diverges once b triples if the input is delayed by one
sample or more (alpha/b = 1/3 is close to the estimator's stability edge ~0.24, and the delay
moves that edge up). Choose alpha near the largest expected input gain.

Run:  .venv/bin/python examples/intelligent_vs_pid.py
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from flatfree.controllers.intelligent import IP

A_DRAG = 0.5  # 1/(unit s): drag coefficient of the plant
B_NOM = 2.0  # nominal input gain
DT = 0.01  # s, sample time
T_END = 10.0  # s
T_SWITCH = 4.0  # s, the gain changes here


def plant(y: float, b: float, u: float) -> float:
    """y' = -a y|y| + b u."""
    return -A_DRAG * y * abs(y) + b * u


def reference(t: float) -> tuple[float, float]:
    """y_ref and its derivative."""
    return 1.0 + 0.5 * math.sin(0.8 * t), 0.4 * math.cos(0.8 * t)


class ClassicPI:
    """u = Kc (e + (1/Ti) int e dt), e = y_ref - y (Astrom & Murray, Feedback Systems, 10.1)."""

    def __init__(self, kc: float, ti: float, dt: float) -> None:
        self.kc, self.ti, self.dt, self.i = kc, ti, dt, 0.0

    def step(self, y: float, y_ref: float, y_ref_dot: float = 0.0) -> float:
        e = y_ref - y
        self.i += e * self.dt
        return self.kc * (e + self.i / self.ti)


def nominal_pi() -> ClassicPI:
    # y' = -2 a dy + b u at y = 1; closed loop s^2 + (2a + b Kc) s + b Kc/Ti = (s + 5)^2
    kc = (2.0 * 5.0 - 2.0 * A_DRAG) / B_NOM
    return ClassicPI(kc=kc, ti=B_NOM * kc / 25.0, dt=DT)


def simulate(ctrl, factor: float, delay: int) -> dict[str, np.ndarray]:
    """Closed loop; plant integrated with 4 RK4 sub-steps per sample (input held)."""
    n = int(round(T_END / DT))
    t = np.arange(n) * DT
    y_log, r_log, u_log = np.empty(n), np.empty(n), np.empty(n)
    y = 1.0
    queue = [0.0] * delay
    for k in range(n):
        r, rd = reference(t[k])
        u = ctrl.step(y, r, rd)
        queue.append(u)
        ua = queue.pop(0)
        y_log[k], r_log[k], u_log[k] = y, r, ua
        b = B_NOM * (1.0 if t[k] < T_SWITCH else factor)
        h = DT / 4
        for _ in range(4):
            k1 = plant(y, b, ua)
            k2 = plant(y + 0.5 * h * k1, b, ua)
            k3 = plant(y + 0.5 * h * k2, b, ua)
            k4 = plant(y + h * k3, b, ua)
            y += h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return {"t": t, "y": y_log, "r": r_log, "u": u_log}


def main() -> None:
    runs = {}
    print(f"{'gain':>6s} {'delay':>6s} {'iP max|e|':>10s} {'PI max|e|':>10s}   (t >= 1 s)")
    for factor in (0.3, 3.0):
        for delay in (0, 1, 2):
            res = {}
            for name, ctrl in (
                ("iP", IP(alpha=2.0 * B_NOM, kp=5.0, dt=DT, window=10)),
                ("PI", nominal_pi()),
            ):
                res[name] = simulate(ctrl, factor, delay)
            m = {k: np.abs(v["y"] - v["r"])[v["t"] >= 1.0].max() for k, v in res.items()}
            print(f"{factor:6.1f} {delay:6d} {m['iP']:10.4f} {m['PI']:10.4f}")
            runs[factor, delay] = res

    fig, axes = plt.subplots(3, 2, figsize=(10, 8), sharex=True)
    for col, factor in enumerate((0.3, 3.0)):
        res = runs[factor, 2]
        ax = axes[0, col]
        ax.plot(res["iP"]["t"], res["iP"]["r"], "k--", lw=1, label="reference")
        ax.plot(res["iP"]["t"], res["iP"]["y"], label="iP (model-free)")
        ax.plot(res["PI"]["t"], res["PI"]["y"], label="PI (nominal tuning)")
        ax.set_title(f"b -> {factor:g} b_nom at t = {T_SWITCH:g} s, 2-sample input delay")
        ax.set_ylabel("y")
        ax = axes[1, col]
        for name in ("iP", "PI"):
            ax.plot(res[name]["t"], res[name]["y"] - res[name]["r"], label=name)
        ax.set_ylabel("e = y - y_ref")
        ax = axes[2, col]
        for name in ("iP", "PI"):
            ax.plot(res[name]["t"], res[name]["u"], label=name)
        ax.set_ylabel("applied u")
        ax.set_xlabel("t [s]")
        for a in axes[:, col]:
            a.axvline(T_SWITCH, color="grey", lw=0.8)
            a.grid(True, alpha=0.3)
    axes[0, 0].legend(loc="lower left")
    axes[1, 0].legend(loc="lower left")
    fig.suptitle(
        "y' = -a y|y| + b(t) u(t - d): iP (alpha = 2 b_nom, Kp = 5/s) vs PI (poles -5, -5)"
    )
    fig.tight_layout()
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
