#!/usr/bin/python3
"""The tables of docs/measurements.md, made from the runs' own outputs (deploy/report.sh).

Subcommands (each prints Markdown on stdout; a bad input exits 2 with a message):

  bench BENCH_JSON       a benchmark's Google Benchmark JSON (--benchmark_out_format=json):
                         mean / median / stddev of the wall-clock time and the CPU time per case
  latency TEST_OUTPUT    the latency suite's table (the text latency_suite_test prints
                         between "[ latency ]" and "per50/per99:") as a Markdown table
  vps-budget CSV         vps_budget_bench's CSV: per config and budget the share of ticks
                         stopped early, the force and torque error against the full cycle,
                         the time per tick
  cyclictest HISTFILE    cyclictest's histogram (--histfile, one thread): one line saying how
                         late the machine alone wakes a SCHED_FIFO thread every 1 ms
  explore3d-features ROUTE_TXT --run LABEL=RUN_DIR...
                         deploy/explore3d.sh's per-feature table: one row per run (RUN_DIR/truth.csv),
                         one column per feature of the route (ROUTE_TXT: hemm-operator
                         --print-hand6-route), each "RMS error of the true peak (% of it), contact ticks"
  explore3d-table --run SCENE|VARIANT|RTT=OUT...
                         deploy/explore3d_table.sh's table: per scene its features and the whole run
                         (rows), per round trip and variant (columns), from explore3d.sh's --out
                         directory OUT (OUT/route.txt, OUT/<RTT>ms/truth.csv and truth.json)
  markdown-rows FILE     the Markdown table rows ("|" lines) of a script's output, as they are
  section NAME TITLE     one section of the document, with its heading, command, date, machine
                         and condition (--command, --date, --machine, --condition), the table
                         from --table FILE (or --missing REASON); between markers, so a later
                         run can replace it alone
  merge DOC SECTION...   DOC with each SECTION file's section put in its place (in the order
                         of the --order NAME=TITLE options), the sections not given kept from
                         DOC, or marked missing

Only the Python standard library.
"""
import argparse
import json
import math
import re
import sys

BEGIN = "<!-- report.sh section: {} -->"
END = "<!-- report.sh end: {} -->"
HEADER = """# Measurements

Every table below is produced by `deploy/report.sh` from the outputs of the runs it names
(it is not edited by hand). Each section gives the command that produced it, the date, the
machine and its condition: figures taken on a machine shared with other work are not hemm's
figures, and say so. Everything here runs in simulation (SIMULATED devices, robot and sensors;
the truth is the simulation's own geometry).

Regenerate all of it on an idle machine with

```
bash deploy/report.sh build/release --condition "idle: nothing else running"
```

"""


class InputError(Exception):
    pass


def md_table(header, rows, align=None):
    """A Markdown table; align: one of 'l'/'r' per column (default: first left, rest right)."""
    align = align or ["l"] + ["r"] * (len(header) - 1)
    if len(align) != len(header) or any(len(r) != len(header) for r in rows):
        raise InputError("table rows do not match the header's %d columns" % len(header))
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" if a == "l" else "--:" for a in align) + "|"]
    cell = lambda c: str(c).replace("|", "\\|")  # "|F|max" stays one cell
    out[0] = "| " + " | ".join(cell(h) for h in header) + " |"
    out += ["| " + " | ".join(cell(c) for c in r) + " |" for r in rows]
    return "\n".join(out) + "\n"


def num(v):
    """Three significant figures, without an exponent (1234.5 -> 1235, 0.01234 -> 0.0123)."""
    if v == 0 or abs(v) >= 100:
        return "%.0f" % v
    digits = 2 - int(math.floor(math.log10(abs(v))))
    return "%.*f" % (digits, v)


def bench_table(bench):
    """bench: Google Benchmark's JSON output (dict). Aggregates (mean/median/stddev) where the
    case repeated, else the single run. Times in the benchmark's own unit."""
    if not isinstance(bench, dict) or not isinstance(bench.get("benchmarks"), list):
        raise InputError("not Google Benchmark JSON (no \"benchmarks\" list)")
    cases = {}
    for b in bench["benchmarks"]:
        try:
            # The run's settings are not the case's name: /repeats:5, /min_time:2.000, /real_time.
            name = re.sub(r"/(repeats:\d+|min_time:[\d.]+s?|iterations:\d+|real_time|manual_time)", "",
                          b.get("run_name") or b["name"])
            t, unit = float(b["real_time"]), b["time_unit"]
        except (KeyError, TypeError, ValueError) as e:
            raise InputError("benchmark entry without name/real_time/time_unit: %s" % e)
        c = cases.setdefault(name, {"unit": unit})
        kind = b.get("aggregate_name") if b.get("run_type") == "aggregate" else "single"
        c[kind] = t
        if kind in ("single", "median") and "cpu_time" in b:
            c["cpu"] = float(b["cpu_time"])
        if "bytes_per_second" in b and kind in ("single", "median"):
            c["bytes_per_second"] = float(b["bytes_per_second"])
    if not cases:
        raise InputError("no benchmarks in the JSON")
    rows = []
    for name, c in cases.items():
        f = lambda k: num(c[k]) if k in c else "-"
        median = f("median") if "median" in c else f("single")
        rate = "%.0f MB/s" % (c["bytes_per_second"] / 1e6) if "bytes_per_second" in c else "-"
        rows.append([name, c["unit"], f("mean"), median, f("stddev"), f("cpu"), rate])
    return md_table(["case", "unit", "mean", "median", "stddev", "CPU time", "throughput"], rows)


def latency_table(text):
    """The latency suite's printed table as Markdown: two header lines (names, units), one row per run."""
    lines = text.splitlines()
    try:
        start = next(i for i, l in enumerate(lines) if "[ latency ]" in l)
    except StopIteration:
        raise InputError("no \"[ latency ]\" table in the latency suite's output")
    body = []
    for l in lines[start + 1:]:
        if l.startswith("per50/per99:") or not l.strip():
            break
        body.append(l)
    if len(body) < 3:
        raise InputError("the latency table has no runs")
    split = lambda l: [t for t in l.split() if t != "|"]
    names = split(body[0])
    # The units line has blanks where a column has no unit, and a name may be wider than its
    # column: a unit belongs to the name whose span holds the unit's last character.
    spans = [(m.start(), m.end()) for m in re.finditer(r"\S+", body[0]) if m.group() != "|"]
    header = list(names)
    for m in re.finditer(r"\S+", body[1]):
        if m.group() == "|":
            continue
        at = [i for i, (a, b) in enumerate(spans) if a < m.end() <= b]
        if len(at) != 1:
            raise InputError("latency table: unit %r under no column name" % m.group())
        header[at[0]] += " " + m.group()
    rows = [split(l) for l in body[2:]]
    for r in rows:
        if len(r) != len(header):
            raise InputError("latency row with %d columns, header has %d: %r" % (len(r), len(header), " ".join(r)))
    return md_table(header, rows)


VPS_BUDGET_COLUMNS = ("config", "mode", "budget_units", "budget_us", "ticks", "contact_ticks", "stopped_early_share",
                      "f_rms_N", "f_max_N", "f_rms_pct", "t_rms_Nm", "t_max_Nm", "cpu_median_us", "cpu_p99_us",
                      "time_median_us", "time_p99_us", "ns_per_unit")


def vps_budget_table(text):
    """vps_budget_bench's CSV as one row per config and budget, in the file's order."""
    import csv
    import io
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows:
        raise InputError("no rows in the vps_budget_bench CSV")
    missing = [c for c in VPS_BUDGET_COLUMNS if c not in rows[0]]
    if missing:
        raise InputError("vps_budget_bench CSV: no column %s" % ", ".join(missing))
    out = []
    for r in rows:
        try:
            v = {k: float(r[k]) for k in VPS_BUDGET_COLUMNS[2:]}
        except (TypeError, ValueError):
            raise InputError("vps_budget_bench CSV: a non-numeric cell in %r" % r)
        mode = r["mode"]
        if mode == "work":
            budget = "{:,} units".format(int(v["budget_units"]))
        elif mode == "time":
            budget = "%.0f µs (%s ns/unit)" % (v["budget_us"], num(v["ns_per_unit"]))
        elif mode == "full":
            budget = "full cycle"
        else:
            raise InputError("vps_budget_bench CSV: mode %r" % mode)
        out.append([r["config"], budget, "%.1f %%" % (100 * v["stopped_early_share"]),
                    "%.3f (%.1f %%)" % (v["f_rms_N"], v["f_rms_pct"]), "%.3f" % v["f_max_N"],
                    "%.5f" % v["t_rms_Nm"], "%.5f" % v["t_max_Nm"],
                    "%s / %s" % (num(v["cpu_median_us"]), num(v["cpu_p99_us"])),
                    "%s / %s" % (num(v["time_median_us"]), num(v["time_p99_us"])), "%d" % v["contact_ticks"]])
    return md_table(["config", "budget", "stopped early", "F error RMS N (% of RMS)", "F max N", "τ error RMS N m",
                     "τ max N m", "CPU µs median / p99", "wall µs median / p99", "contact ticks"],
                    out, ["l", "l"] + ["r"] * 8)


def cyclictest_line(text, late_us=500):
    """One sentence from cyclictest's --histfile of one thread: wakes, how many were more than
    late_us late (beyond the histogram counts as late), the median and p99 of the lateness and
    its maximum."""
    bins, total, overflows, maximum = [], None, 0, None
    for line in text.splitlines():
        if line.startswith("#"):
            key, _, value = line[1:].partition(":")
            key, value = key.strip(), value.strip()
            try:
                if key == "Total":
                    total = int(value.split()[0])
                elif key == "Histogram Overflows":
                    overflows = int(value.split()[0])
                elif key == "Max Latencies":
                    maximum = int(value.split()[0])
            except (ValueError, IndexError):
                raise InputError("cyclictest: bad line %r" % line)
            continue
        f = line.split()
        if not f:
            continue
        if len(f) != 2:
            raise InputError("cyclictest: one thread's histogram expected, got %r" % line)
        try:
            bins.append((int(f[0]), int(f[1])))
        except ValueError:
            raise InputError("cyclictest: bad line %r" % line)
    if not bins or total is None or maximum is None:
        raise InputError("cyclictest: no histogram, total or maximum")
    if sum(c for _, c in bins) + overflows != total:
        raise InputError("cyclictest: the histogram does not add up to its total")
    late = sum(c for b, c in bins if b > late_us) + overflows

    def quantile(q):
        need, seen = q * total, 0
        for b, c in bins:
            seen += c
            if seen >= need:
                return "%d" % b
        return "> %d" % bins[-1][0]
    return ("The machine alone (cyclictest, SCHED_FIFO 80, memory locked, a 1 ms interval): "
            "%d of %d wakes more than %d µs late (%.3f %%); lateness median %s µs, p99 %s µs, max %d µs.\n"
            % (late, total, late_us, 100.0 * late / total if total else 0.0, quantile(0.5), quantile(0.99), maximum))


def markdown_rows(text):
    """The Markdown tables in a script's output (runs of "|" lines), as they are, a blank line between."""
    blocks, cur = [], []
    for l in text.splitlines() + [""]:
        if l.startswith("|"):
            cur.append(l)
        elif cur:
            blocks.append(cur)
            cur = []
    blocks = [b for b in blocks if len(b) >= 3 and re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", b[1].replace(" ", ""))]
    if not blocks:
        raise InputError("no Markdown table in the output")
    return "\n\n".join("\n".join(b) for b in blocks) + "\n"


def read_route(text, where="route"):
    """hemm-operator --print-hand6-route's output: {"scene", "route", "start", "region", "end", "features"}."""
    r = {"features": []}
    for n, line in enumerate(text.splitlines(), 1):
        w = line.split()
        if not w:
            continue
        try:
            if w[0] in ("scene", "route") and len(w) == 2:
                r[w[0]] = w[1]
            elif w[0] == "start" and len(w) == 4:
                r["start"] = [float(x) for x in w[1:]]
            elif w[0] == "region" and len(w) == 7:
                r["region"] = [float(x) for x in w[1:]]
            elif w[0] == "end" and len(w) == 2:
                r["end"] = float(w[1])
            elif w[0] == "feature" and len(w) == 4:
                r["features"].append((w[1], float(w[2]), float(w[3])))
            else:
                raise ValueError
        except ValueError:
            raise InputError("%s:%d: not a route line: %r" % (where, n, line))
    for k in ("scene", "route", "start", "region", "end"):
        if k not in r:
            raise InputError("%s: no %s line" % (where, k))
    if not r["features"]:
        raise InputError("%s: no features" % where)
    return r


def feature_errors(truth_csv, features, where="truth.csv"):
    """Per feature (name, t0, t1): (force error RMS N, true force peak N, contact ticks) over the ticks
    of the hand's script time t in [t0, t1] (one period a tick: t = tick / 1000) where the live or
    the true tool touches (hemm-truth --tool6 --csv)."""
    lines = truth_csv.splitlines()
    if not lines:
        raise InputError("%s: empty" % where)
    head = lines[0].split(",")
    need = ["tick", "f_x", "f_y", "f_z", "ft_x", "ft_y", "ft_z", "contacts", "contacts_true"]
    if any(k not in head for k in need):
        raise InputError("%s: not hemm-truth --tool6 --csv output (columns %s)" % (where, ", ".join(need)))
    ix = [head.index(k) for k in need]
    acc = [[0.0, 0.0, 0] for _ in features]
    for n, line in enumerate(lines[1:], 2):
        c = line.split(",")
        if len(c) != len(head):
            raise InputError("%s:%d: %d columns, expected %d" % (where, n, len(c), len(head)))
        try:
            tick, fx, fy, fz, tx, ty, tz, live, true = (float(c[i]) for i in ix)
        except ValueError:
            raise InputError("%s:%d: not numbers" % (where, n))
        if live == 0 and true == 0:
            continue
        t = tick * 1e-3
        for a, (_, t0, t1) in zip(acc, features):
            if t0 <= t <= t1:
                a[0] += (fx - tx) ** 2 + (fy - ty) ** 2 + (fz - tz) ** 2
                a[1] = max(a[1], math.sqrt(tx * tx + ty * ty + tz * tz))
                a[2] += 1
    return [(math.sqrt(e2 / k) if k else None, peak, k) for e2, peak, k in acc]


def error_cell(rms, peak, ticks=None):
    """ "RMS of PEAK (P %)", the share of the true peak; "no contact" when nothing touched."""
    if rms is None:
        return "no contact"
    share = " (%.0f %%)" % (100.0 * rms / peak) if peak > 0 else ""
    return "%.2f of %.1f%s%s" % (rms, peak, share, ", %d" % ticks if ticks is not None else "")


def read_file(path):
    try:
        return open(path, encoding="utf-8").read()
    except OSError as e:
        raise InputError("%s: %s" % (path, e.strerror or e))


def explore3d_features_table(route, runs):
    """runs: [(label, truth_csv_text)]; one row a run, one column a feature of the route."""
    rows = []
    for label, text in runs:
        rows.append([label] + [error_cell(*e) for e in feature_errors(text, route["features"], label)])
    return md_table(["run"] + [f[0] for f in route["features"]], rows)


def explore3d_table(runs):
    """runs: [(scene, variant, rtt, out_dir)]: rows scene x (features, whole run), columns rtt x variant."""
    cols, scenes, cells = [], [], {}
    for scene, variant, rtt, out in runs:
        col = "%s ms, %s" % (rtt, variant)
        if col not in cols:
            cols.append(col)
        route = read_route(read_file("%s/route.txt" % out), "%s/route.txt" % out)
        if scene not in [s for s, _ in scenes]:
            scenes.append((scene, route))
        elif [f[0] for f in dict(scenes)[scene]["features"]] != [f[0] for f in route["features"]]:
            raise InputError("%s: another route than the scene's other runs" % out)
        run = "%s/%sms" % (out, rtt)
        errs = feature_errors(read_file(run + "/truth.csv"), route["features"], run + "/truth.csv")
        for (name, _, _), e in zip(route["features"], errs):
            cells[(scene, name, col)] = error_cell(*e[:2])
        try:
            j = json.loads(read_file(run + "/truth.json"))
            whole = (j["force_rms_n"], j["true_force_peak_n"]) if j.get("contact_ticks", 0) else (None, 0.0)
        except (ValueError, KeyError) as e:
            raise InputError("%s/truth.json: not hemm-truth --json output (%s)" % (run, e))
        cells[(scene, "whole run", col)] = error_cell(*whole)
    rows = []
    for scene, route in scenes:
        for name in [f[0] for f in route["features"]] + ["whole run"]:
            rows.append([scene, name] + [cells.get((scene, name, c), "not run") for c in cols])
    return md_table(["scene", "feature"] + cols, rows, ["l", "l"] + ["r"] * len(cols))


def section(name, title, command, date, machine, condition, table=None, missing=None, note=None):
    if not re.fullmatch(r"[a-z0-9-]+", name):
        raise InputError("section name %r: lower-case letters, digits, '-'" % name)
    out = [BEGIN.format(name), '<a id="%s"></a>' % name, "", "## " + title, ""]  # measurements.md#NAME
    if missing is not None:
        out += ["*Missing:* " + missing, ""]
    else:
        out += ["- command: `%s`" % command, "- date: %s" % date, "- machine: %s" % machine,
                "- condition: %s" % condition, ""]
        if note:
            out += [note, ""]
        out += [table.rstrip("\n"), ""]
    out.append(END.format(name))
    return "\n".join(out) + "\n"


def split_sections(doc):
    """{name: text} of the sections between markers in a document."""
    found = {}
    for m in re.finditer(r"<!-- report\.sh section: ([a-z0-9-]+) -->\n.*?<!-- report\.sh end: \1 -->\n?", doc, re.S):
        found[m.group(1)] = m.group(0) if m.group(0).endswith("\n") else m.group(0) + "\n"
    return found


def merge(doc, new, order, titles):
    """The document: HEADER, then for each name in order the new section, else the old one from doc,
    else a section marked missing."""
    old = split_sections(doc)
    parts = [HEADER]
    for name in order:
        if name in new:
            parts.append(new[name])
        elif name in old:
            parts.append(old[name])
        else:
            parts.append(section(name, titles.get(name, name), None, None, None, None,
                                 missing="not produced yet (deploy/report.sh --only %s)." % name))
        parts.append("\n")
    return "".join(parts).rstrip("\n") + "\n"


def main(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("bench").add_argument("file")
    sub.add_parser("latency").add_argument("file")
    sub.add_parser("markdown-rows").add_argument("file")
    sub.add_parser("vps-budget").add_argument("file")
    sub.add_parser("cyclictest").add_argument("file")
    f = sub.add_parser("explore3d-features")
    f.add_argument("route")
    f.add_argument("--run", action="append", required=True, help="LABEL=RUN_DIR (RUN_DIR/truth.csv)")
    t = sub.add_parser("explore3d-table")
    t.add_argument("--run", action="append", required=True, help="SCENE|VARIANT|RTT=OUT (explore3d.sh --out)")
    s = sub.add_parser("section")
    s.add_argument("name")
    s.add_argument("title")
    for k in ("command", "date", "machine", "condition", "table", "missing", "note"):
        s.add_argument("--" + k)
    m = sub.add_parser("merge")
    m.add_argument("doc")
    m.add_argument("sections", nargs="*")
    m.add_argument("--order", required=True, action="append", help="NAME=TITLE, once per section, in order")
    a = p.parse_args(argv)
    try:
        if a.cmd in ("bench", "latency", "markdown-rows", "vps-budget", "cyclictest"):
            text = open(a.file, encoding="utf-8").read()
            if a.cmd == "bench":
                try:
                    text = json.loads(text)
                except ValueError as e:
                    raise InputError("%s: not JSON: %s" % (a.file, e))
            sys.stdout.write({"bench": bench_table, "latency": latency_table, "markdown-rows": markdown_rows,
                              "vps-budget": vps_budget_table, "cyclictest": cyclictest_line}[a.cmd](text))
        elif a.cmd == "explore3d-features":
            route = read_route(read_file(a.route), a.route)
            runs = []
            for spec in a.run:
                label, eq, d = spec.partition("=")
                if not eq or not label:
                    raise InputError("--run %r: LABEL=RUN_DIR" % spec)
                runs.append((label, read_file(d + "/truth.csv")))
            sys.stdout.write(explore3d_features_table(route, runs))
        elif a.cmd == "explore3d-table":
            runs = []
            for spec in a.run:
                key, eq, out = spec.partition("=")
                k = key.split("|")
                if not eq or len(k) != 3 or not all(k) or not re.fullmatch(r"[0-9]+", k[2]):
                    raise InputError("--run %r: SCENE|VARIANT|RTT=OUT (RTT whole milliseconds)" % spec)
                runs.append((k[0], k[1], k[2], out))
            sys.stdout.write(explore3d_table(runs))
        elif a.cmd == "section":
            if a.missing is None and (a.table is None or None in (a.command, a.date, a.machine, a.condition)):
                raise InputError("section: --table with --command, --date, --machine, --condition, or --missing")
            table = open(a.table, encoding="utf-8").read() if a.missing is None else None
            sys.stdout.write(section(a.name, a.title, a.command, a.date, a.machine, a.condition, table, a.missing, a.note))
        else:
            pairs = [x.split("=", 1) for x in a.order]
            if any(len(x) != 2 for x in pairs):
                raise InputError("--order: NAME=TITLE")
            titles = dict(pairs)
            try:
                doc = open(a.doc, encoding="utf-8").read()
            except FileNotFoundError:
                doc = ""
            new = {}
            for f in a.sections:
                got = split_sections(open(f, encoding="utf-8").read())
                if len(got) != 1:
                    raise InputError("%s: not one report.sh section" % f)
                new.update(got)
            sys.stdout.write(merge(doc, new, [x[0] for x in pairs], titles))
    except (InputError, OSError) as e:
        print("report_tables: %s" % e, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
