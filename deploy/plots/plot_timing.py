#!/usr/bin/python3
"""The deadline histogram of one run (Debian's python3-matplotlib, Agg backend).

Input: a --station-json of hemm-operator (any run: the networked station, the
bimanual device, a VPS scene: its "timing" object) or of hemm-robot (its
"control_timing"), or hemm-robot's --stats-json (robot.control_timing). They
hold proto/report.proto's ServoTiming: log-spaced histograms (128 bins per
octave of microseconds) of the loop's wake lateness, compute and period, the
ten worst ticks with what ran in them, and, beside a servo loop, the
SIMULATED hardware thread's own timing.

Output: one PNG (default FILE.timing.png): the three histograms on a log time
axis with the period and the miss thresholds marked, the simulated hardware's
compute and period beside them when the run had one, and the worst ticks.

Usage: plot_timing.py FILE [--out PNG] [--title TEXT]
"""
import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def find_timing(j):
    """The ServoTiming object of a report, and what it is of."""
    if isinstance(j.get("timing"), dict):
        return j["timing"], "servo loop"
    if isinstance(j.get("control_timing"), dict):
        return j["control_timing"], "robot control loop"
    if isinstance(j.get("robot"), dict) and isinstance(j["robot"].get("control_timing"), dict):
        return j["robot"]["control_timing"], "robot control loop"
    raise ValueError("no timing / control_timing object (a --station-json of hemm-operator or hemm-robot?)")


def num(v):
    return float(v) if v is not None else 0.0


def draw_hist(ax, h, label, colour):
    lo = [num(x) for x in h.get("bin_lower", [])]
    hi = [num(x) for x in h.get("bin_upper", [])]
    n = [num(x) for x in h.get("bin_count", [])]
    if not n:
        return False
    # Bin 0 is [0, 1 us): drawn from 0.5 us on the log axis.
    lo = [max(x, 0.5) for x in lo]
    hi = [max(y, x * 1.01) for x, y in zip(lo, hi)]
    ax.bar(lo, n, width=[y - x for x, y in zip(lo, hi)], align="edge", color=colour, alpha=0.6, label=label,
           edgecolor=colour, linewidth=0.3)
    return True


def panel(ax, t, title):
    period = num(t.get("period_target_us")) or 1000.0
    late = num(t.get("late_wake_threshold_us")) or 500.0
    drawn = False
    drawn |= draw_hist(ax, t.get("compute_us", {}), "compute", "tab:blue")
    drawn |= draw_hist(ax, t.get("wake_latency_us", {}), "wake lateness", "tab:red")
    drawn |= draw_hist(ax, t.get("period_us", {}), "period", "tab:green")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("us")
    ax.set_ylabel("ticks per bin (bins: 1/128 octave)")
    ax.axvline(period, color="k", linestyle="--", linewidth=0.8, label=f"period {period:.0f} us")
    ax.axvline(late, color="tab:red", linestyle=":", linewidth=0.8, label=f"late wake > {late:.0f} us")
    ticks = int(num(t.get("ticks")))
    misses = int(num(t.get("misses")))
    share = 100.0 * misses / ticks if ticks else 0.0
    c = t.get("compute_us", {})
    p = t.get("period_us", {})
    w = t.get("wake_latency_us", {})
    ax.set_title(
        f"{title}: {ticks} ticks, {misses} misses ({share:.3f} %)\n"
        f"compute median {num(c.get('median')):.1f} p99 {num(c.get('p99')):.1f} max {num(c.get('max')):.0f} us; "
        f"wake p99 {num(w.get('p99')):.1f} us; period p99 {num(p.get('p99')):.1f} us",
        fontsize=9)
    if drawn:
        ax.legend(fontsize=7, loc="upper right")
    return drawn


def worst_text(t):
    lines = ["worst ticks (wake lateness + compute):"]
    for w in t.get("worst_ticks", []):
        what = w.get("renderer", "")
        work = int(num(w.get("work")))
        lines.append(f"  #{int(num(w.get('tick')))}: wake {num(w.get('wake_latency_us')):+.0f} us, "
                     f"compute {num(w.get('compute_us')):.0f} us" + (f", {what}" if what else "") +
                     (f" work {work}" if work else ""))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("json")
    ap.add_argument("--out", default=None)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    try:
        with open(a.json) as f:
            t, what = find_timing(json.load(f))
    except (OSError, ValueError) as e:
        print(f"plot_timing.py: {a.json}: {e}", file=sys.stderr)
        return 2
    hw = t.get("simulated_hardware")
    cols = 2 if isinstance(hw, dict) and hw.get("timing") else 1
    fig, axes = plt.subplots(2, cols, figsize=(7 * cols, 8.5), gridspec_kw={"height_ratios": [3, 1.3]},
                             squeeze=False)
    flags = []
    flags.append("SCHED_FIFO" if t.get("fifo") else "no SCHED_FIFO")
    cpu = int(num(t.get("cpu", -1)))
    flags.append(f"pinned to CPU {cpu}" if cpu >= 0 else "not pinned")
    panel(axes[0][0], t, f"{what} ({', '.join(flags)})")
    axes[1][0].axis("off")
    axes[1][0].text(0, 1, worst_text(t), va="top", family="monospace", fontsize=7)
    if cols == 2:
        ht = hw["timing"]
        panel(axes[0][1], ht, f"SIMULATED hardware ({hw.get('device', '')}, {hw.get('mode', '')})")
        age = hw.get("sample_age_us", {})
        axes[1][1].axis("off")
        axes[1][1].text(0, 1,
                        f"sample age at the servo's read: median {num(age.get('median')):.0f} us, "
                        f"p99 {num(age.get('p99')):.0f} us\n"
                        f"hardware steps with a new command {int(num(hw.get('commands_new')))}, "
                        f"holding the last {int(num(hw.get('commands_held')))}\n\n" + worst_text(ht),
                        va="top", family="monospace", fontsize=7)
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    out = a.out or (a.json + ".timing.png")
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"plot_timing.py: wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
