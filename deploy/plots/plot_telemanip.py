#!/usr/bin/python3
"""Both hands' forces over one telemanipulation run (Debian's python3-matplotlib, Agg backend).

Input: a run's folder of deploy/telemanip_table.sh --truth-trace (or any pair
of files): hands.csv from hemm-operator --hand-trace (what each hand was given
to feel, its held-object share, the remote wrist force as the operator
believed it) and, if present, truth.csv from hemm-robot --truth-trace (the
SIMULATION ONLY contact force on each gripper). The two line up on their
clock_s columns (the steady clock: one host).

Output: one PNG (default DIR/forces.png): per hand (right above, left
below) |F| felt by the hand, its held-object share, the remote wrist force as
believed (late by the link) and the true contact force on the gripper, on
the operator's time axis; the grasp phases of the remote grippers shaded.

Usage: plot_telemanip.py DIR [--hands CSV] [--truth CSV] [--out PNG] [--title TEXT]
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")
    return rows


def norm3(r, prefix):
    return math.sqrt(sum(float(r[f"{prefix}_{a}"]) ** 2 for a in "xyz"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", help="a run's folder (hands.csv, truth.csv)")
    ap.add_argument("--hands", help="the hand trace (default DIR/hands.csv)")
    ap.add_argument("--truth", help="the truth trace (default DIR/truth.csv if there)")
    ap.add_argument("--out", help="PNG to write (default DIR/forces.png)")
    ap.add_argument("--title", default="", help="the figure's title")
    a = ap.parse_args()
    hands_path = a.hands or os.path.join(a.dir, "hands.csv")
    truth_path = a.truth or os.path.join(a.dir, "truth.csv")
    out = a.out or os.path.join(a.dir, "forces.png")
    try:
        hands = read_csv(hands_path)
        truth = read_csv(truth_path) if (a.truth or os.path.exists(truth_path)) else None
        if "clock_s" not in hands[0] or (truth and "clock_s" not in truth[0]):
            raise ValueError("a trace without clock_s (an older hemm?): cannot line them up")
    except (OSError, ValueError, KeyError) as e:
        print(f"plot_telemanip: {e}", file=sys.stderr)
        return 2
    c0 = float(hands[0]["clock_s"])
    t = [float(r["clock_s"]) - c0 for r in hands]
    mode = hands[-1]["mode"]
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True)
    for ax, side in zip(axes, ("right", "left")):
        held = [r[f"{side}_holding"] == "1" for r in hands]
        # Shade where the remote gripper held (believed).
        start = None
        for i, h in enumerate(held + [False]):
            if h and start is None:
                start = t[i]
            elif not h and start is not None:
                ax.axvspan(start, t[i - 1], color="0.92", lw=0)
                start = None
        ax.plot(t, [norm3(r, f"{side}_felt") for r in hands], lw=0.9, label="felt by the hand |F| (as in A)")
        if mode == "model":
            ax.plot(t, [norm3(r, f"{side}_held") for r in hands], lw=0.8, ls="--", label="its held-object share")
        ax.plot(t, [norm3(r, f"{side}_remote_force") for r in hands], lw=0.8,
                label="remote wrist force, as believed")
        if truth:
            tt = [float(r["clock_s"]) - c0 for r in truth]
            ax.plot(tt, [norm3(r, f"{side}_force") for r in truth], lw=0.6, alpha=0.7,
                    label="true contact on the gripper (SIMULATION ONLY)")
        ax.set_ylabel(f"{side} hand [N]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8, ncol=2)
    axes[-1].set_xlabel("time [s] (operator's clock; grey: the remote gripper holds, as believed)")
    fig.suptitle(a.title or f"telemanipulation, {mode} mode: {os.path.basename(os.path.normpath(a.dir))}")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
