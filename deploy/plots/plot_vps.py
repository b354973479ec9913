#!/usr/bin/python3
"""Plots of one hemm-operator VPS run (Debian's python3-matplotlib, Agg backend).

Input: the 1 kHz VPS log written with `hemm-operator --config <a vps config> --log FILE`.
Output (PNG, into --out, default beside FILE):

  FILE.wrench.png  force and torque against time for each arm (end-effector 0 = right,
                   1 = left), as the device received them (frame H)
  FILE.contact.png penetration per pair, energy the device gave each hand (passivity
                   observer; above zero = generated), VPS time per tick

Usage: plot_vps.py FILE [--out DIR] [--title TEXT]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{path}: empty file")
        cols = {h: [] for h in header}
        for row in reader:
            if len(row) != len(header):
                continue  # a row cut short when the writer stopped
            try:
                vals = [float(x) for x in row]
            except ValueError:
                continue
            for h, v in zip(header, vals):
                cols[h].append(v)
    if not cols.get("t_ns"):
        raise ValueError(f"{path}: no rows")
    return cols


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log")
    ap.add_argument("--out", default=None)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    try:
        c = read_csv(a.log)
    except (OSError, ValueError) as e:
        print(f"plot_vps.py: {e}", file=sys.stderr)
        return 2
    out = a.out or os.path.dirname(os.path.abspath(a.log))
    os.makedirs(out, exist_ok=True)
    base = os.path.join(out, os.path.basename(a.log))
    t0 = c["t_ns"][0]
    t = [(x - t0) * 1e-9 for x in c["t_ns"]]
    arms = 2 if max(c["ees"]) >= 2 else 1
    names = ["right (end-effector 0)", "left (end-effector 1)"]
    fig, axes = plt.subplots(2, arms, figsize=(6 * arms, 6), sharex=True, squeeze=False)
    for k in range(arms):
        for row, (key, unit) in enumerate([("f", "force [N]"), ("tau", "torque [N m]")]):
            ax = axes[row][k]
            for axis in "xyz":
                ax.plot(t, c[f"{key}{k}_{axis}"], lw=0.8, label=axis)
            ax.set_ylabel(unit)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(names[k])
            else:
                ax.set_xlabel("time [s]")
            ax.legend(loc="upper right", fontsize=8)
    fig.suptitle(a.title or "wrench sent to the device (frame H)")
    fig.tight_layout()
    fig.savefig(base + ".wrench.png", dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for key, label in [("pen_rs", "right-scene"), ("pen_ls", "left-scene"), ("pen_rl", "right-left")]:
        axes[0].plot(t, [1e3 * x for x in c[key]], lw=0.8, label=label)
    axes[0].set_ylabel("max penetration [mm]")
    axes[0].legend(fontsize=8)
    for k in range(arms):
        axes[1].plot(t, c[f"energy{k}"], lw=0.8, label=names[k])
    axes[1].axhline(0, color="k", lw=0.5)
    axes[1].set_ylabel("energy to the hand [J]")
    axes[1].legend(fontsize=8)
    axes[2].plot(t, [x * 1e-3 for x in c["vps_ns"]], lw=0.5)
    axes[2].set_ylabel("VPS per tick [us]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(a.title or "contacts, passivity observer, compute")
    fig.tight_layout()
    fig.savefig(base + ".contact.png", dpi=110)
    plt.close(fig)
    print(f"wrote {base}.wrench.png, {base}.contact.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
