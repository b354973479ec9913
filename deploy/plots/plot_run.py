#!/usr/bin/python3
"""Plots of one hemm-operator run (Debian's python3-matplotlib, Agg backend).

Inputs: the 1 kHz servo log written with `hemm-operator --log FILE` and, if
present beside it, FILE.world.csv (per tick, frame W) and FILE.map.csv (the
final local map's segments). Outputs PNGs into --out (default: beside FILE):

  force_time.png   |F| and its components vs time, mode shaded   (HEMM Fig. 8 style)
  force_path.png   |F| vs the proxy's position along its path      (HEMM Fig. 9 style)
  map_topdown.png  map segments, the robot's path, the proxy's path (needs the W logs)
  force_truth.png  |F| from the local model against |F| from the true scene, and
                   their difference, vs time (with --truth: hemm-truth --csv output;
                   SIMULATION ONLY)

Usage: plot_run.py FILE [--out DIR] [--title TEXT] [--truth TRUTH.csv]
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MODE_NAMES = {0: "unspecified", 1: "idle", 2: "navigation", 3: "manipulation", 4: "exploration"}
MODE_COLOURS = {2: "#d9ead3", 3: "#fce5cd", 4: "#cfe2f3"}


def read_runs(path, key, convert=str):
    """Rows (dicts of strings) grouped by column `key` (its values through
    `convert`), in file order; an error for an empty file or a missing column."""
    runs = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        if not reader.fieldnames or key not in reader.fieldnames:
            raise ValueError(f"{path}: no column '{key}'")
        for r in reader:
            runs.setdefault(convert(r[key]), []).append(r)
    if not runs:
        raise ValueError(f"{path}: no rows")
    return runs


def read_csv(path):
    """Columns as lists of floats; rows with a wrong field count are skipped."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{path}: empty file")
        cols = {h: [] for h in header}
        bad = 0
        for row in reader:
            if len(row) != len(header):
                bad += 1
                continue
            try:
                vals = [float(x) for x in row]
            except ValueError:
                bad += 1
                continue
            for h, v in zip(header, vals):
                cols[h].append(v)
    if bad:
        print(f"{path}: skipped {bad} malformed rows", file=sys.stderr)
    return cols


def seconds(t_ns):
    if not t_ns:
        return []
    t0 = t_ns[0]
    return [(t - t0) * 1e-9 for t in t_ns]


def shade_modes(ax, t, mode):
    """Background bands for each run of one mode."""
    if not t:
        return
    start = 0
    for i in range(1, len(t) + 1):
        if i == len(t) or mode[i] != mode[start]:
            m = int(mode[start])
            if m in MODE_COLOURS:
                ax.axvspan(t[start], t[i - 1], color=MODE_COLOURS[m], alpha=0.6, lw=0,
                           label=MODE_NAMES.get(m, str(m)))
            start = i
    # one legend entry per mode
    handles, labels = ax.get_legend_handles_labels()
    seen = {}
    for h, lab in zip(handles, labels):
        seen.setdefault(lab, h)
    ax.legend(seen.values(), seen.keys(), loc="upper right", fontsize=8)


def plot_force_time(servo, out, title):
    t = seconds(servo["t_ns"])
    fx, fy, fz = servo["fx"], servo["fy"], servo["fz"]
    fn = [math.sqrt(a * a + b * b + c * c) for a, b, c in zip(fx, fy, fz)]
    fig, ax = plt.subplots(figsize=(9, 4))
    shade_modes(ax, t, servo["mode"])
    ax.plot(t, fn, "k-", lw=1.2, label="|F|")
    ax.plot(t, fx, lw=0.6, label="F_x (H)")
    ax.plot(t, fy, lw=0.6, label="F_y (H)")
    ax.plot(t, fz, lw=0.6, label="F_z (H)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force on the device [N]")
    ax.set_title(f"{title}: force vs time")
    ax.grid(True, alpha=0.3)
    h, lab = ax.get_legend_handles_labels()
    ax.legend(h, lab, loc="upper left", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def plot_force_path(servo, world, out, title):
    """|F| against the arc length travelled by the proxy (W if available, else H)."""
    if world is not None:
        px, py = world["proxy_x"], world["proxy_y"]
        fn = [math.hypot(a, b) for a, b in zip(world["fw_x"], world["fw_y"])]
        unit = "m (W)"
    else:
        px, py = servo["proxy_x"], servo["proxy_y"]
        fn = [math.sqrt(a * a + b * b + c * c) for a, b, c in zip(servo["fx"], servo["fy"], servo["fz"])]
        unit = "m (device H)"
    s = [0.0]
    for i in range(1, len(px)):
        s.append(s[-1] + math.hypot(px[i] - px[i - 1], py[i] - py[i - 1]))
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(s, fn, "b-", lw=1.0)
    ax.set_xlabel(f"proxy position along its path [{unit}]")
    ax.set_ylabel("|F| [N]")
    ax.set_title(f"{title}: force vs proxy position")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def plot_map(world, segments, out, title):
    fig, ax = plt.subplots(figsize=(7, 7))
    if segments is not None:
        for ax_, ay, bx, by in zip(segments["ax"], segments["ay"], segments["bx"], segments["by"]):
            ax.plot([ax_, bx], [ay, by], "k-", lw=1.0)
    ax.plot(world["robot_x"], world["robot_y"], "g-", lw=2.0, label="robot (predicted)")
    ax.plot(world["proxy_x"], world["proxy_y"], "r-", lw=0.8, label="proxy")
    ax.plot(world["goal_x"], world["goal_y"], ":", color="orange", lw=0.6, label="interaction point")
    if world["robot_x"]:
        x, y, th = world["robot_x"][-1], world["robot_y"][-1], world["robot_theta"][-1]
        ax.arrow(x, y, 0.3 * math.cos(th), 0.3 * math.sin(th), width=0.02, color="g")
    ax.set_aspect("equal", adjustable="datalim")
    save(fig, ax, out, f"{title}: local map (black), paths", "x_W [m]", "y_W [m]", legend="best")


def save(fig, ax, out, title, xlabel, ylabel, legend=None):
    """Labels, grid, optional legend; writes the PNG and closes the figure."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if legend:
        ax.legend(loc=legend, fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)


def plot_force_truth(truth, out, title):
    t = truth["t_s"]
    fr = [math.hypot(a, b) for a, b in zip(truth["fr_x"], truth["fr_y"])]
    ft = [math.hypot(a, b) for a, b in zip(truth["ft_x"], truth["ft_y"])]
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, fr, "b-", lw=1.0, label="|F| local model (rendered)")
    ax.plot(t, ft, "k--", lw=1.0, label="|F| true scene (same path)")
    ax.plot(t, truth["df"], "r-", lw=0.6, alpha=0.7, label="|F_local - F_true|")
    save(fig, ax, out, f"{title}: rendered force against the true scene's (SIMULATION ONLY)", "time [s]",
         "force [N]", legend="upper left")


def main(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", help="servo CSV written by hemm-operator --log")
    p.add_argument("--out", help="output directory (default: the log's directory)")
    p.add_argument("--title", default=None)
    p.add_argument("--truth", help="per-tick CSV from hemm-truth --csv (adds force_truth.png)")
    a = p.parse_args(argv)
    out = a.out or os.path.dirname(os.path.abspath(a.log))
    os.makedirs(out, exist_ok=True)
    title = a.title or os.path.basename(a.log)
    try:
        servo = read_csv(a.log)
    except (OSError, ValueError) as e:
        print(f"plot_run: {e}", file=sys.stderr)
        return 2
    for col in ("t_ns", "fx", "fy", "fz", "mode", "proxy_x", "proxy_y"):
        if col not in servo:
            print(f"plot_run: {a.log}: no column {col}: not a servo log", file=sys.stderr)
            return 2
    world = read_csv(a.log + ".world.csv") if os.path.exists(a.log + ".world.csv") else None
    segments = read_csv(a.log + ".map.csv") if os.path.exists(a.log + ".map.csv") else None
    written = []
    plot_force_time(servo, os.path.join(out, "force_time.png"), title)
    written.append("force_time.png")
    plot_force_path(servo, world, os.path.join(out, "force_path.png"), title)
    written.append("force_path.png")
    if world is not None:
        plot_map(world, segments, os.path.join(out, "map_topdown.png"), title)
        written.append("map_topdown.png")
    if a.truth:
        try:
            truth = read_csv(a.truth)
        except (OSError, ValueError) as e:
            print(f"plot_run: {e}", file=sys.stderr)
            return 2
        missing = [c for c in ("t_s", "fr_x", "fr_y", "ft_x", "ft_y", "df") if c not in truth]
        if missing:
            print(f"plot_run: {a.truth}: no column {missing[0]}: not a hemm-truth --csv file", file=sys.stderr)
            return 2
        plot_force_truth(truth, os.path.join(out, "force_truth.png"), title)
        written.append("force_truth.png")
    print("wrote " + ", ".join(os.path.join(out, w) for w in written))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
