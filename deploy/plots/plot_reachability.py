#!/usr/bin/python3
"""The workspace of the SIMULATED bimanual interface, as the bimanual paper's Fig. 2.

Input: the CSV of `hemm-bimanual-workspace -o FILE` (section,x,y,z,right,left in
frame D of the rig: x forward towards the column, y to the operator's left, z up
from the table top; right/left: each arm's reachability index, the fraction of
sampled flange orientations its IK reaches). Output: bimanual_reachability.png
in --out (default: beside FILE): for the horizontal and the vertical section,
the right arm's index, the left arm's, and the overlapping workspace (points
both arms reach, coloured by the smaller index). As in the paper, blue marks
points where more than 75 % of the orientations are reached, red less than 8 %.

Usage: plot_reachability.py FILE [--out DIR]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402

# Red below 8 %, blue above 75 %, shades between (the paper's two thresholds).
BOUNDS = [0.0, 0.08, 0.25, 0.5, 0.75, 1.0001]
CMAP = ListedColormap(["#d7191c", "#fdae61", "#ffffbf", "#abd9e9", "#2c7bb6"])


def read(path):
    rows = {}
    with open(path, newline="") as f:
        r = csv.DictReader(f)
        need = {"section", "x", "y", "z", "right", "left"}
        if not r.fieldnames or not need.issubset(r.fieldnames):
            raise ValueError(f"{path}: expected columns {sorted(need)}")
        for row in r:
            try:
                v = [float(row[k]) for k in ("x", "y", "z", "right", "left")]
            except ValueError:
                continue
            rows.setdefault(row["section"], []).append(v)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    try:
        rows = read(a.file)
    except (OSError, ValueError) as e:
        print(e, file=sys.stderr)
        return 2
    sections = [s for s in ("horizontal", "vertical") if s in rows]
    if not sections:
        print(f"{a.file}: no horizontal or vertical section", file=sys.stderr)
        return 2
    out = a.out or os.path.dirname(os.path.abspath(a.file))
    os.makedirs(out, exist_ok=True)
    norm = BoundaryNorm(BOUNDS, CMAP.N)
    fig, axes = plt.subplots(len(sections), 3, figsize=(13, 3.9 * len(sections)), squeeze=False,
                             constrained_layout=True)
    for r, name in enumerate(sections):
        pts = rows[name]
        # Horizontal: y across, x forward (up the page); vertical: y across, z up.
        if name == "horizontal":
            u, v = (lambda p: p[1]), (lambda p: p[0])
            vlab = f"section z = {pts[0][2]:.2f} m\nx [m] (to the column)"
        else:
            u, v = (lambda p: p[1]), (lambda p: p[2])
            vlab = f"section x = {pts[0][0]:.2f} m\nz [m] above the table"
        panels = (("right arm", lambda p: p[3]), ("left arm", lambda p: p[4]),
                  ("both arms (smaller index)", lambda p: min(p[3], p[4]) if p[3] > 0 and p[4] > 0 else 0.0))
        anywhere = [p for p in pts if p[3] > 0 or p[4] > 0] or pts
        lim_u = (min(u(p) for p in anywhere) - 0.1, max(u(p) for p in anywhere) + 0.1)
        lim_v = (min(v(p) for p in anywhere) - 0.1, max(v(p) for p in anywhere) + 0.1)
        for c, (what, idx) in enumerate(panels):
            ax = axes[r][c]
            reached = [p for p in pts if idx(p) > 0]
            missed = [p for p in pts if idx(p) <= 0]
            ax.scatter([u(p) for p in missed], [v(p) for p in missed], s=4, c="#cccccc", marker=".")
            sc = ax.scatter([u(p) for p in reached], [v(p) for p in reached], s=45, c=[idx(p) for p in reached],
                            cmap=CMAP, norm=norm, edgecolors="k", linewidths=0.3)
            if r == 0:
                ax.set_title(what, fontsize=11)
            ax.set_xlabel("y [m] (operator's left)")
            if c == 0:
                ax.set_ylabel(vlab)
            ax.set_xlim(*lim_u)
            ax.set_ylim(*lim_v)
            ax.set_aspect("equal")
            ax.grid(True, alpha=0.3)
    cb = fig.colorbar(sc, ax=axes, ticks=BOUNDS[:-1] + [1.0], shrink=0.8)
    cb.set_label("reachability index (blue > 0.75, red < 0.08)")
    fig.suptitle("SIMULATED bimanual interface: reachability index of the flange (fraction of sampled orientations the IK reaches)")
    path = os.path.join(out, "bimanual_reachability.png")
    fig.savefig(path, dpi=90)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
