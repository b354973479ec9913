#!/usr/bin/python3
"""Plots of deploy/explore3d.sh's runs (6-DoF probe tool on the live voxmap, issue 13;
Debian's python3-matplotlib, Agg backend). SIMULATION ONLY truth.

Inputs: for each run, the per-tick CSV of `hemm-truth --tool6 ... --csv` (live and true
force / torque in W, tool and goal positions) and, for the image, the live voxmap's
surface voxels the operator wrote at stop (RUN.csv.voxmap.csv: x,y,z,sdf in W).

Outputs:
  WRENCH_PNG  |F| and |tau| against time, live (from the 1 cm live voxmap) and true (the same
              hand path against the 2.5 mm voxmap of the true scene), one column per run
  VOXMAP_PNG  the live voxmap's surface voxels (coloured by height) with the tool tip's path

Usage: plot_explore3d.py --wrench WRENCH_PNG --voxmap VOXMAP_PNG --voxcsv VOXMAP_CSV
                         --run LABEL=TRUTH_CSV [--run LABEL=TRUTH_CSV ...]
                         [--region XMIN YMIN ZMIN XMAX YMAX ZMAX] [--heading DEG]
"""
import argparse
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_columns(path):
    with open(path, newline="") as f:
        r = csv.reader(f)
        header = next(r, None)
        if header is None:
            raise ValueError(f"{path}: empty file")
        cols = {h: [] for h in header}
        for row in r:
            if len(row) != len(header):
                continue
            for h, v in zip(header, row):
                cols[h].append(float(v))
    return cols


def norm3(c, a, b, d):
    return [math.sqrt(x * x + y * y + z * z) for x, y, z in zip(c[a], c[b], c[d])]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--wrench", required=True)
    ap.add_argument("--voxmap", help="the live voxmap and tool path image (with --voxcsv)")
    ap.add_argument("--voxcsv")
    ap.add_argument("--title", default="6-DoF probe tool on the live voxmap: block, book, mug (SIMULATION)")
    ap.add_argument("--run", action="append", required=True, help="LABEL=TRUTH_CSV")
    ap.add_argument("--region", type=float, nargs=6, default=[1.0, 1.55, 0.70, 2.0, 2.45, 0.95],
                    metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
                    help="the voxels shown and the axes, W (default: home.xml's table top)")
    ap.add_argument("--heading", type=float, default=90.0,
                    help="the robot's heading in W, degrees: the view is from behind it (default home's, 90)")
    a = ap.parse_args()
    runs = []
    for spec in a.run:
        if "=" not in spec:
            sys.exit(f"plot_explore3d: --run wants LABEL=CSV, got '{spec}'")
        label, path = spec.split("=", 1)
        runs.append((label, read_columns(path)))

    fig, axes = plt.subplots(2, len(runs), figsize=(7 * len(runs), 6), sharex=True, squeeze=False)
    for k, (label, c) in enumerate(runs):
        t = [i * 1e-3 for i in c["tick"]]  # the hand's script time (one servo period per tick)
        for row, (name, live, true, unit) in enumerate(
            [("force", norm3(c, "f_x", "f_y", "f_z"), norm3(c, "ft_x", "ft_y", "ft_z"), "N"),
             ("torque", norm3(c, "tau_x", "tau_y", "tau_z"), norm3(c, "taut_x", "taut_y", "taut_z"), "N m")]):
            ax = axes[row][k]
            ax.plot(t, true, color="k", lw=1.6, label="truth (2.5 mm voxmap of the scene)")
            ax.plot(t, live, color="tab:red", lw=0.8, label="live voxmap (1 cm, from depth clouds)")
            ax.set_ylabel(f"|{name}| [{unit}]")
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(label)
                ax.legend(loc="upper right", fontsize=8)
            else:
                ax.set_xlabel("script time [s]")
    fig.suptitle(a.title)
    fig.tight_layout()
    fig.savefig(a.wrench, dpi=110)
    if not (a.voxmap and a.voxcsv):
        return 0

    v = read_columns(a.voxcsv)
    c = runs[0][1]
    fig = plt.figure(figsize=(9, 7))
    ax = fig.add_subplot(111, projection="3d")
    x0, y0, z0, x1, y1, z1 = a.region
    keep = [i for i, (x, y, z) in enumerate(zip(v["x"], v["y"], v["z"]))
            if x0 <= x <= x1 and y0 <= y <= y1 and z0 <= z <= z1]
    sc = ax.scatter([v["x"][i] for i in keep], [v["y"][i] for i in keep], [v["z"][i] for i in keep],
                    c=[v["z"][i] for i in keep], cmap="viridis", s=4, alpha=0.6, depthshade=False)
    live = [i for i, m in enumerate(c["model"]) if m > 0]  # before the first voxmap the robot pose is not known yet
    touch = [i for i in live if c["contacts"][i] > 0]
    ax.plot([c["tool_x"][i] for i in live], [c["tool_y"][i] for i in live], [c["tool_z"][i] for i in live],
            color="tab:red", lw=0.8, label="tool tip centre (live)")
    ax.scatter([c["tool_x"][i] for i in touch[::20]], [c["tool_y"][i] for i in touch[::20]],
               [c["tool_z"][i] for i in touch[::20]], color="tab:red", s=6, label="in contact")
    ax.set_xlabel("W x [m]")
    ax.set_ylabel("W y [m]")
    ax.set_zlabel("W z [m]")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_zlim(z0, max(z1, 1.0))
    ax.view_init(elev=35, azim=a.heading - 210)  # from behind the robot's left shoulder
    fig.colorbar(sc, ax=ax, shrink=0.6, label="surface voxel height [m]")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"Live voxmap (1 cm surface voxels, {len(keep)} shown) and the tool path ({runs[0][0]})")
    fig.tight_layout()
    fig.savefig(a.voxmap, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
