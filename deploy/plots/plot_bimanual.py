#!/usr/bin/python3
"""Plot of one hemm-operator run with the SIMULATED bimanual device.

Input: the 1 kHz servo log of `hemm-operator --device sim-bimanual --log FILE`
(two end-effectors: end-effector 0 the right hand's columns without prefix,
end-effector 1 the left hand's with "ee1_"). Output: bimanual_run.png in --out
(default: beside FILE), four panels over time for both hands:

  1. end-effector position (frame H = D: x forward, y left, z up)
  2. commanded force |F| (the planes) and torque |T| (the orientation springs)
  3. handle inputs: grip lever position and commanded grip force, joystick axes
  4. state: enabled (brakes off), dead-man, clutch attached

Usage: plot_bimanual.py FILE [--out DIR] [--title TEXT]
"""
import argparse
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_run import read_csv  # noqa: E402


def norm3(c, p, a):
    return [math.sqrt(x * x + y * y + z * z) for x, y, z in zip(c[p + a + "x"], c[p + a + "y"], c[p + a + "z"])]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--out", default=None)
    ap.add_argument("--title", default="bimanual (SIMULATED)")
    a = ap.parse_args()
    c = read_csv(a.file)
    if "ee1_dev_x" not in c:
        print(f"{a.file}: not a two-end-effector log (no ee1_ columns)", file=sys.stderr)
        return 2
    out = a.out or os.path.dirname(os.path.abspath(a.file))
    os.makedirs(out, exist_ok=True)
    t0 = c["t_ns"][0]
    t = [(x - t0) * 1e-9 for x in c["t_ns"]]
    hands = [("", "right", "tab:red"), ("ee1_", "left", "tab:blue")]
    fig, ax = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    for p, name, col in hands:
        for axis, style in (("x", ":"), ("y", "--"), ("z", "-")):
            ax[0].plot(t, c[p + "dev_" + axis], style, color=col, lw=1.0, label=f"{name} {axis}")
        ax[1].plot(t, norm3(c, p, "f"), "-", color=col, lw=1.0, label=f"{name} |F| [N]")
        ax[1].plot(t, [10 * v for v in norm3(c, p, "t")], ":", color=col, lw=1.0, label=f"{name} 10 |T| [N m]")
        ax[2].plot(t, [1000 * v for v in c[p + "grip"]], "-", color=col, lw=1.0, label=f"{name} grip lever [mm]")
        ax[2].plot(t, c[p + "grip_force"], "--", color=col, lw=1.0, label=f"{name} grip force [N]")
        ax[2].plot(t, c[p + "joy_x"], ":", color=col, lw=1.0, label=f"{name} joystick x")
        off = 0.0 if p == "" else 0.06
        ax[3].plot(t, [v + off for v in c[p + "enabled"]], "-", color=col, lw=1.2, label=f"{name} enabled")
        ax[3].plot(t, [0.5 * v + off for v in c[p + "deadman"]], "--", color=col, lw=1.0, label=f"{name} dead-man (0.5)")
        ax[3].plot(t, [0.25 * v + off for v in c[p + "attached"]], ":", color=col, lw=1.0, label=f"{name} attached (0.25)")
    ax[0].set_ylabel("end-effector [m] (D)")
    ax[1].set_ylabel("commanded wrench")
    ax[2].set_ylabel("handle")
    ax[3].set_ylabel("state")
    ax[3].set_xlabel("time [s]")
    for x in ax:
        x.grid(True, alpha=0.3)
        x.legend(loc="upper left", fontsize=7, ncol=3)
    ax[0].set_title(f"{a.title}: both hands, 1 kHz servo log")
    fig.tight_layout()
    path = os.path.join(out, "bimanual_run.png")
    fig.savefig(path, dpi=110)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
