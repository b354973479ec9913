#!/usr/bin/python3
"""The force error the time-critical VPS costs (Debian's python3-matplotlib, Agg backend).

Input: the CSV of tests/bench/vps/vps_budget_bench (one row per config and budget).
Output: one PNG (default docs/img/vps_budget.png) with three panels against the VPS CPU
time per tick (median of the ticks, microseconds, log scale), one line per shipped config:

  force error   RMS |F - F_full| over the contact ticks, as a share of the RMS contact
                force (work budgets: line; the time budgets 50-500 us: markers)
  torque error  RMS |tau - tau_full| over the contact ticks [N m] (a share of a torque near
                zero, a flat face resting flat, says little)
  stopped early share of ticks whose budget ran out before the finest level

Usage: plot_vps_budget.py CSV [--out PNG] [--title TEXT]
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

NUM = ("budget_units", "budget_us", "stopped_early_share", "f_rms_pct", "t_rms_pct", "time_median_us",
       "time_p99_us", "f_rms_N", "f_max_N", "cpu_median_us", "cpu_p99_us", "t_rms_Nm")


def read_rows(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")
    for r in rows:
        for k in NUM:
            if k not in r:
                raise ValueError(f"{path}: no column {k}")
            r[k] = float(r[k])
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--out", default="docs/img/vps_budget.png")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    try:
        rows = read_rows(a.csv)
    except (OSError, ValueError) as e:
        print(f"plot_vps_budget.py: {e}", file=sys.stderr)
        return 2
    configs = []
    for r in rows:
        if r["config"] not in configs:
            configs.append(r["config"])
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
    panels = (("f_rms_pct", "force error, RMS % of RMS contact force"),
              ("t_rms_Nm", "torque error, RMS [N m]"),
              ("stopped_early_share", "share of ticks stopped early"))
    for i, name in enumerate(configs):
        color = f"C{i}"
        mine = [r for r in rows if r["config"] == name]
        work = sorted((r for r in mine if r["mode"] == "work"), key=lambda r: r["budget_units"])
        timed = [r for r in mine if r["mode"] == "time"]
        full = [r for r in mine if r["mode"] == "full"]
        for p, (key, _) in enumerate(panels):
            scale = 100.0 if key == "stopped_early_share" else 1.0
            ax[p].plot([r["cpu_median_us"] for r in work], [scale * r[key] for r in work], "-", color=color,
                       lw=1.2, label=name.replace("operator_", "") if p == 0 else None)
            ax[p].plot([r["cpu_median_us"] for r in timed], [scale * r[key] for r in timed], "o", color=color,
                       ms=5, mfc="none")
            for r in timed:
                if r["budget_us"] in (50.0, 200.0, 500.0):
                    ax[p].annotate(f"{r['budget_us']:.0f}", (r["cpu_median_us"], scale * r[key]), fontsize=7,
                                   color=color, xytext=(3, 3), textcoords="offset points")
            if full:
                ax[p].axvline(full[0]["cpu_median_us"], color=color, lw=0.6, ls=":")
    for p, (_, label) in enumerate(panels):
        ax[p].set_xscale("log")
        ax[p].set_xlabel("VPS CPU time per tick, median [us]  (dotted: full cycle)")
        ax[p].set_ylabel(label if p < 2 else "stopped early [%]")
        ax[p].set_title(label, fontsize=9)
        ax[p].grid(True, which="both", alpha=0.3)
    ax[0].set_yscale("symlog", linthresh=0.1)
    ax[1].set_yscale("symlog", linthresh=1e-4)
    ax[0].set_ylim(bottom=0)
    ax[1].set_ylim(bottom=0)
    ax[2].set_ylim(0, 105)
    ax[0].legend(fontsize=8, title="line: work budgets; o: time budget [us]", title_fontsize=7)
    fig.suptitle(a.title or "Time-critical VPS on the shipped configs' poses: error against the full cycle")
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    fig.savefig(a.out, dpi=110)
    print(a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
