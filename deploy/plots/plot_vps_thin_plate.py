#!/usr/bin/python3
"""Force against height of a sphere pushed through a thin plate (issue 23 item 6).

Input: the CSV of `vps_thin_plate_sweep CSV` (tests/bench/vps): per tick the
sphere centre's height, whether the sphere overlaps the plate, the two exact
references (the half-space behind the face it came through, the volumetric
overlap with the plate) and the model's force and contacts at 1, 2 and 4 mm
voxels. Optionally --before CSV, the same sweep on the code before the fix,
drawn faintly.

Output: one PNG (default docs/img/vps_thin_plate.png): the vertical force
against the height (left: the whole pass, right: around separation, where
the sphere's top leaves the plate's lower face).

Usage: plot_vps_thin_plate.py CSV [--before CSV] [--out PNG]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

VOXELS = (1, 2, 4)
COLOURS = {1: "tab:blue", 2: "tab:orange", 4: "tab:green"}


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")
    need = ["centre_z_mm", "overlap", "ref_halfspace_n", "ref_plate_overlap_n"] + [f"fz_{v}mm_n" for v in VOXELS]
    missing = [k for k in need if k not in rows[0]]
    if missing:
        raise ValueError(f"{path}: missing columns {missing}")
    cols = {k: [float(r[k]) for r in rows] for k in rows[0]}
    return cols


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--before", default=None)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "..", "docs", "img",
                                                  "vps_thin_plate.png"))
    a = ap.parse_args()
    try:
        c = read(a.csv)
        b = read(a.before) if a.before else None
    except (OSError, ValueError) as e:
        print(f"plot_vps_thin_plate.py: {e}", file=sys.stderr)
        return 2
    z = c["centre_z_mm"]
    # Separation: the first height (going down) where the sphere no longer overlaps after having done so.
    sep = None
    seen = False
    for zi, ov in zip(z, c["overlap"]):
        seen = seen or ov > 0
        if seen and ov == 0:
            sep = zi
            break
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), gridspec_kw={"width_ratios": [1.5, 1]})
    for ax, (lo, hi) in zip(axes, [(min(z), max(z)), ((sep or 0) - 14, (sep or 0) + 6)]):
        if b is not None:
            for v in VOXELS:
                ax.plot(b["centre_z_mm"], b[f"fz_{v}mm_n"], color=COLOURS[v], lw=0.8, alpha=0.35, ls=":",
                        label=f"before the fix, {v} mm voxels")
        for v in VOXELS:
            ax.plot(z, c[f"fz_{v}mm_n"], color=COLOURS[v], lw=1.2, label=f"model, {v} mm voxels")
        ax.plot(z, c["ref_halfspace_n"], color="k", lw=1.0, ls="--",
                label="exact: half-space behind the face it came through (K x volume below it), 0 once apart")
        ax.plot(z, c["ref_plate_overlap_n"], color="0.5", lw=1.0, ls="-.",
                label="exact: K x volume shared with the plate")
        if sep is not None:
            ax.axvspan(lo, sep, color="0.9", zorder=0)
            ax.axvline(sep, color="0.3", lw=0.8)
        ax.axhline(0, color="0.3", lw=0.5)
        ax.set_xlim(hi, lo)  # pushed down: height decreases to the right
        ax.set_xlabel("sphere centre height above the plate's top face (mm)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("vertical force on the sphere (N, + = up)")
    axes[0].set_title("20 mm sphere pushed down through a 1 mm plate (K 1e7 N/m^3, 3 layers)", fontsize=10)
    axes[1].set_title("around separation (shaded: no part of the sphere overlaps the plate)", fontsize=10)
    lo1, hi1 = (sep or 0) - 14, (sep or 0) + 6
    window = [i for i, zi in enumerate(z) if lo1 <= zi <= hi1]
    vals = [c[f"fz_{v}mm_n"][i] for v in VOXELS for i in window] + [c["ref_plate_overlap_n"][i] for i in window]
    if b is not None:
        vals += [b[f"fz_{v}mm_n"][i] for v in VOXELS for i in window if i < len(b[f"fz_{v}mm_n"])]
    if vals:
        span = max(vals) - min(vals)
        axes[1].set_ylim(min(vals) - 0.05 * span - 0.1, max(vals) + 0.05 * span + 0.1)
    axes[0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    out = os.path.abspath(a.out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
