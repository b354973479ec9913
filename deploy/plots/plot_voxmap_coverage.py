#!/usr/bin/python3
"""How the live voxmap falls into place as the robot sees more (issue 13).

Input: the CSV of `voxmap_sweep OUT_DIR` (tests/bench/probe3d; columns drop,
t_s, chunks_integrated, coverage, force_rms_N, force_max_N, contact_ticks,
cells): after every SIMULATED mast-camera frame of the first 3 s, integrated
into a 1 cm live voxmap ahead of the robot with 0 %, 5 % or 20 % of the chunks
dropped at random, the fraction of the truly visible surface within one voxel
of a rendered cell, and the 3-DoF probe's force error (RMS over contact ticks:
all of them, solid; on the tops of the table, block and book, dashed)
along the fixed path over the table top, the block and the book against the
exact truth voxmap. Output: voxmap_coverage.png in --out (default: beside FILE).

Usage: plot_voxmap_coverage.py FILE [--out DIR]
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
        runs = read_runs(a.file, "drop", float)
    except (OSError, ValueError) as e:
        sys.exit(str(e))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for drop, rows in sorted(runs.items()):
        t = [float(r["t_s"]) for r in rows]
        label = "%.0f %% of chunks dropped" % (100 * drop)
        line, = ax1.plot(t, [100 * float(r["coverage"]) for r in rows], marker=".", label=label)
        ax2.plot(t, [float(r["force_rms_N"]) for r in rows], marker=".", color=line.get_color(), label=label + ": all")
        ax2.plot(t, [float(r["force_rms_tops_N"]) for r in rows], linestyle="--", color=line.get_color(),
                 label=label + ": tops")
    ax1.set_ylabel("visible surface covered [%]")
    ax1.set_ylim(0, 100)
    ax1.grid(True, alpha=0.3)
    ax1.legend(loc="lower right")
    ax1.set_title("Live voxmap, 1 cm, ahead of the robot (SIMULATED mast camera)")
    ax2.set_ylabel("probe force error, RMS [N]")
    ax2.set_ylim(bottom=0)
    ax2.legend(loc="upper right", fontsize="small", ncol=2)
    ax2.set_xlabel("time since the first frame [s]")
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    out = a.out or os.path.dirname(os.path.abspath(a.file))
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "voxmap_coverage.png")
    fig.savefig(path, dpi=110)
    print(path)


if __name__ == "__main__":
    main()
