#!/usr/bin/python3
"""The ROI's coverage against time, fixed mast against the active gaze (issue 24).

Input: the CSV of `gaze_coverage OUT_DIR` (tests/bench/probe3d; SIMULATION
ONLY: the robot before the home scene's table, the explore-table script's
tool path driving the gaze): per run and every 0.2 s snapshot, the share of
the ROI's true surface (what either head position could see) within one
voxel of a rendered cell, the same near the tool (0.15 m), per feature, and
the head's true pan. Output: gaze_coverage.png (--out, default beside FILE).

Usage: plot_gaze_coverage.py FILE [--out PNG]
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_run import read_runs  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    try:
        runs = read_runs(a.file, "run")
    except (OSError, ValueError) as e:
        sys.exit(str(e))
    fig, axes = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
    for name, rows in runs.items():
        t = [float(r["t_s"]) for r in rows]
        axes[0].plot(t, [100 * float(r["roi"]) for r in rows], label=name)
        axes[1].plot(t, [100 * float(r["near_tool"]) if r["near_tool"] != "nan" else float("nan") for r in rows],
                     label=name)
        axes[2].plot(t, [100 * (float(r["block_left"]) + float(r["mug_top"]) + float(r["book_front"])) / 3
                         for r in rows], label=name)
        axes[3].plot(t, [float(r["pan_deg"]) for r in rows], label=name)
    axes[0].set_ylabel("ROI coverage %")
    axes[1].set_ylabel("within 0.15 m\nof the tool %")
    axes[2].set_ylabel("block left, mug top,\nbook front (mean) %")
    axes[3].set_ylabel("head pan (true) deg")
    axes[3].set_xlabel("time s (explore-table script)")
    axes[0].set_title("Live voxmap coverage of the true surface, fixed mast vs active gaze (SIMULATION)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    out = a.out or os.path.join(os.path.dirname(os.path.abspath(a.file)), "gaze_coverage.png")
    fig.savefig(out, dpi=110)
    print("wrote " + out)


if __name__ == "__main__":
    main()
