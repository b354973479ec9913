#!/usr/bin/python3
"""What each hand felt against what its remote gripper met (SIMULATION ONLY truth).

For each run folder of deploy/telemanip_table.sh --truth-trace (hands.csv from
hemm-operator --hand-trace, truth.csv from hemm-robot --truth-trace, both on
the steady clock of one host) and per hand: the force the hand was given to
feel (felt_{x,y,z}: the device's force in A at G, divided by the translation
scale) against the true contact force on that gripper (MuJoCo's, in A), the
truth taken one way delay later (the round trip's half, from the folder's
name: a command made at t reaches the robot then, so what the hand feels at
t is what the robot should meet then). Over the contact samples (either
force above 1 N): the RMS and the largest |felt - true|, and the RMS of the
true force for scale.

Usage: telemanip_force_error.py RUN_DIR [RUN_DIR ...] [--json OUT.json]
Prints one line per run and hand; exits 2 on a folder without both traces.
"""
import argparse
import bisect
import csv
import json
import math
import os
import re
import sys

CONTACT_N = 1.0


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def vec(r, prefix):
    return [float(r[f"{prefix}_{a}"]) for a in "xyz"]


def force_error(run_dir):
    """{'right': {...}, 'left': {...}} for one run folder."""
    hands = read_rows(os.path.join(run_dir, "hands.csv"))
    truth = read_rows(os.path.join(run_dir, "truth.csv"))
    if not hands or not truth:
        raise ValueError(f"{run_dir}: an empty trace")
    m = re.search(r"-(\d+)ms-", os.path.basename(os.path.normpath(run_dir)))
    one_way_s = (int(m.group(1)) / 2000.0) if m else 0.0
    tc = [float(r["clock_s"]) for r in truth]
    out = {}
    for arm in ("right", "left"):
        n = 0
        sq = sq_true = 0.0
        worst = 0.0
        for r in hands:
            t = float(r["clock_s"]) + one_way_s
            if t < tc[0] or t > tc[-1]:
                continue
            i = bisect.bisect_left(tc, t)
            if i > 0 and (i == len(tc) or t - tc[i - 1] < tc[i] - t):
                i -= 1
            if abs(tc[i] - t) > 0.02:  # a gap in the truth trace
                continue
            felt = vec(r, f"{arm}_felt")
            true = vec(truth[i], f"{arm}_force")
            fn = math.sqrt(sum(x * x for x in felt))
            tn = math.sqrt(sum(x * x for x in true))
            if fn < CONTACT_N and tn < CONTACT_N:
                continue
            e = math.sqrt(sum((a - b) ** 2 for a, b in zip(felt, true)))
            n += 1
            sq += e * e
            sq_true += tn * tn
            worst = max(worst, e)
        out[arm] = dict(contact_samples=n, rms_error_n=math.sqrt(sq / n) if n else float("nan"),
                        max_error_n=worst, rms_true_n=math.sqrt(sq_true / n) if n else float("nan"),
                        one_way_s=one_way_s)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="run folders with hands.csv and truth.csv")
    ap.add_argument("--json", help="write the results here")
    a = ap.parse_args()
    results = {}
    for d in a.runs:
        for f in ("hands.csv", "truth.csv"):
            if not os.path.exists(os.path.join(d, f)):
                print(f"telemanip_force_error: {d}: no {f} (run the table with --truth-trace)", file=sys.stderr)
                sys.exit(2)
        try:
            results[d] = force_error(d)
        except (OSError, ValueError, KeyError) as e:
            print(f"telemanip_force_error: {d}: {e}", file=sys.stderr)
            sys.exit(2)
        for arm, r in results[d].items():
            print(f"{os.path.basename(os.path.normpath(d))} {arm}: {r['contact_samples']} contact samples, "
                  f"felt vs true RMS {r['rms_error_n']:.2f} N (max {r['max_error_n']:.1f} N), true RMS {r['rms_true_n']:.2f} N")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
