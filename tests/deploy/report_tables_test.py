#!/usr/bin/python3
"""deploy/report_tables.py: the tables of docs/measurements.md from the runs' outputs."""
import json
import math
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "deploy"))
import report_tables as rt  # noqa: E402

# Two rows as tests/integration/latency/latency_suite_test.cpp prints them (print_table).
LATENCY = """noise before
[ latency ] round trip through hemm-relay (jitter +-10 % of one-way, >= 1 ms; 5 % loss each way)
run                        rtt rtt_meas |   ticks  per50  per99 wake99 comp99 misses | |F|max  E_gen   E_ep | goal_p  goal_t t_goal contact guard |  dF_rms  dF_max  cF_rms  cF_max pose_e
                            ms      ms |             ms     ms     us     us        |      N     mJ     mJ |      m       m      s   steps    st |       N       N       N       N      m
nav-to-goal                  0     1.5 |   25050  1.000  1.132    242     10    167 |  0.000  0.000  0.000 |  0.046   0.075   16.7       0     0 |   0.000   0.000   0.000   0.000  0.037
probe-cylinder             300   300.8 |   18150  1.000  1.289    384      6    134 |  0.258  0.000 -0.000 |      -       -      -       0     0 |   0.010   0.157   0.019   0.157  0.000
per50/per99: servo period median/p99 from the 1 kHz log
"""


def cells(line):
    return [c.strip() for c in line.strip().strip("|").split(" | ")]


class LatencyTable(unittest.TestCase):
    def test_header_takes_each_columns_unit_and_rows_keep_their_values(self):
        lines = rt.latency_table(LATENCY).splitlines()
        self.assertEqual(len(lines), 4)
        head = cells(lines[0])
        self.assertEqual(len(head), 22)
        self.assertEqual(head[:4], ["run", "rtt ms", "rtt_meas ms", "ticks"])
        self.assertIn("\\|F\\|max N", head)  # the pipe inside a name is escaped, its unit found by position
        self.assertEqual(head[-1], "pose_e m")
        row = cells(lines[3])
        self.assertEqual(row[0], "probe-cylinder")
        self.assertEqual(row[head.index("cF_rms N")], "0.019")
        self.assertEqual(row[head.index("goal_t m")], "-")

    def test_output_without_the_table_or_with_a_short_row_is_refused(self):
        with self.assertRaises(rt.InputError):
            rt.latency_table("no table here\n")
        broken = LATENCY.replace("0.000  0.037", "0.037")
        with self.assertRaises(rt.InputError):
            rt.latency_table(broken)


class BenchTable(unittest.TestCase):
    def test_aggregates_per_case_and_single_runs(self):
        bench = {"benchmarks": [
            {"name": "BM_Seal/16/repeats:5_mean", "run_name": "BM_Seal/16/repeats:5", "run_type": "aggregate", "aggregate_name": "mean",
             "real_time": 812.5, "time_unit": "ns"},
            {"name": "BM_Seal/16_median", "run_name": "BM_Seal/16", "run_type": "aggregate",
             "aggregate_name": "median", "real_time": 800.0, "cpu_time": 790.0, "time_unit": "ns",
             "bytes_per_second": 2.0e7},
            {"name": "BM_Seal/16_stddev", "run_name": "BM_Seal/16", "run_type": "aggregate",
             "aggregate_name": "stddev", "real_time": 12.25, "time_unit": "ns"},
            {"name": "BM_Replay/min_time:2.000/real_time", "run_name": "BM_Replay/min_time:2.000/real_time", "run_type": "iteration", "real_time": 3.5,
             "cpu_time": 3.4, "time_unit": "ns"},
        ]}
        lines = rt.bench_table(bench).splitlines()
        self.assertEqual(cells(lines[0]), ["case", "unit", "mean", "median", "stddev", "CPU time", "throughput"])
        self.assertEqual(cells(lines[2]), ["BM_Seal/16", "ns", "812", "800", "12.2", "790", "20 MB/s"])
        self.assertEqual(cells(lines[3]), ["BM_Replay", "ns", "-", "3.50", "-", "3.40", "-"])

    def test_numbers_have_three_figures_and_no_exponent(self):
        self.assertEqual([rt.num(v) for v in (141000.0, 1234.5, 98.76, 3.99, 0.012345, 0)],
                         ["141000", "1234", "98.8", "3.99", "0.0123", "0"])

    def test_not_benchmark_json_is_refused(self):
        for bad in ({}, {"benchmarks": []}, {"benchmarks": [{"name": "x"}]}, []):
            with self.assertRaises(rt.InputError):
                rt.bench_table(bad)


VPS_BUDGET = """config,mode,budget_units,budget_us,ticks,contact_ticks,stopped_early_share,f_rms_N,f_max_N,f_rms_pct,t_rms_Nm,t_max_Nm,t_rms_pct,cpu_median_us,cpu_p99_us,time_median_us,time_p99_us,time_max_us,work_median,work_max,over_time,ns_per_unit
operator_vps_peg,work,2048,0.0,4300,1589,1.000000,0.113,0.146,4.7000,0.00193,0.00262,2.1,41.3,249,40.7,4468,9000,2048,2048,0,0.000
operator_vps_peg,time,0,200.0,4300,1589,0.782000,0.115,0.276,4.7200,0.00213,0.00825,2.2,67.0,348,70.1,300,900,1800,4000,3,41.250
operator_vps_peg,full,0,0.0,4300,1589,0.000000,0,0,0.0000,0,0,0,232,641,240,700,900,8562,9114,0,0.000
"""


class VpsBudgetTable(unittest.TestCase):
    def test_one_row_per_budget_with_its_kind_early_share_and_error(self):
        lines = rt.vps_budget_table(VPS_BUDGET).splitlines()
        self.assertEqual(len(lines), 5)
        head = cells(lines[0])
        rows = [cells(l) for l in lines[2:]]
        self.assertEqual([r[head.index("budget")] for r in rows], ["2,048 units", "200 µs (41.2 ns/unit)", "full cycle"])
        self.assertEqual(rows[1][head.index("stopped early")], "78.2 %")
        self.assertEqual(rows[0][head.index("F error RMS N (% of RMS)")], "0.113 (4.7 %)")
        self.assertEqual(rows[2][head.index("CPU µs median / p99")], "232 / 641")

    def test_a_csv_without_its_columns_or_with_an_unknown_mode_is_refused(self):
        with self.assertRaises(rt.InputError):
            rt.vps_budget_table("config,mode\nx,work\n")
        with self.assertRaises(rt.InputError):
            rt.vps_budget_table(VPS_BUDGET.replace(",full,", ",half,"))
        with self.assertRaises(rt.InputError):
            rt.vps_budget_table(VPS_BUDGET.splitlines()[0] + "\n")


# cyclictest --histfile of one thread: 10 wakes, 2 beyond 500 us (one in the histogram, one over it).
CYCLICTEST = """# Histogram
000040 000005
000060 000003
000700 000001
# Total: 000000010
# Min Latencies: 00040
# Avg Latencies: 00200
# Max Latencies: 03000
# Histogram Overflows: 00001
"""


class Cyclictest(unittest.TestCase):
    def test_counts_late_wakes_with_the_overflows_and_gives_median_and_p99(self):
        line = rt.cyclictest_line(CYCLICTEST)
        self.assertIn("2 of 10 wakes more than 500 µs late (20.000 %)", line)
        self.assertIn("median 40 µs", line)
        self.assertIn("p99 > 700 µs", line)  # the 10th wake is past the histogram
        self.assertIn("max 3000 µs", line)

    def test_a_histogram_that_does_not_add_up_or_is_missing_is_refused(self):
        with self.assertRaises(rt.InputError):
            rt.cyclictest_line(CYCLICTEST.replace("Total: 000000010", "Total: 000000011"))
        with self.assertRaises(rt.InputError):
            rt.cyclictest_line("# Total: 0\n")
        with self.assertRaises(rt.InputError):
            rt.cyclictest_line(CYCLICTEST.replace("000060 000003", "000060 000003 000001"))


class Document(unittest.TestCase):
    def sec(self, name, table="| a | b |\n|---|--:|\n| x | 1 |\n"):
        return rt.section(name, "T " + name, "cmd " + name, "2026-01-01", "2 cores", "idle", table)

    def test_markdown_rows_keeps_each_table_and_drops_the_rest(self):
        text = "log\n| a | b |\n|---|--:|\n| x | 1 |\nmiddle\n| c |\n|---|\n| y |\nx\n|not a table|\nend\n"
        self.assertEqual(rt.markdown_rows(text), "| a | b |\n|---|--:|\n| x | 1 |\n\n| c |\n|---|\n| y |\n")
        with self.assertRaises(rt.InputError):
            rt.markdown_rows("| only | a row |\n")

    def test_merge_replaces_given_sections_keeps_others_and_marks_the_rest_missing(self):
        order = ["latency", "link", "rt"]
        titles = {n: "T " + n for n in order}
        first = rt.merge("", {"latency": self.sec("latency"), "link": self.sec("link")}, order, titles)
        self.assertIn("- command: `cmd link`", first)
        self.assertIn("*Missing:* not produced yet", first)
        new_link = self.sec("link", "| a |\n|---|\n| new |\n")
        second = rt.merge(first, {"link": new_link}, order, titles)
        parts = rt.split_sections(second)
        self.assertEqual(list(parts), order)
        self.assertEqual(parts["latency"], rt.split_sections(first)["latency"])
        self.assertIn("| new |", parts["link"])
        self.assertNotIn("| x | 1 |", parts["link"])
        self.assertEqual(rt.merge(second, {}, order, titles), second)  # idempotent
        self.assertTrue(second.startswith(rt.HEADER))

    def test_section_names_are_checked(self):
        with self.assertRaises(rt.InputError):
            rt.section("Bad Name", "t", "c", "d", "m", "c", "| a |\n|---|\n| b |\n")


ROUTE = """scene /x/table.xml
route explore-table
start 0.5 2 0
region 1 1 0.6 2 2 1
end 3.5
feature top 1 2
feature side 3 3.5
"""
TRUTH_HEAD = "tick,t_s,f_x,f_y,f_z,ft_x,ft_y,ft_z,contacts,contacts_true\n"


def truth_rows(rows):
    """rows: (tick, live force, true force, live contacts, true contacts)."""
    return TRUTH_HEAD + "".join("%d,0,%g,%g,%g,%g,%g,%g,%d,%d\n" % ((t,) + tuple(f) + tuple(g) + (c, d))
                                for t, f, g, c, d in rows)


class Explore3dTables(unittest.TestCase):
    # Feature "top" over t in [1, 2] s: ticks 1000 (error (3, 4, 0): 5 N, true |(0, 0, 6)| = 6 N) and
    # 2000 (error 0, true 8 N); tick 1500 touches neither and does not count; tick 2500 is between
    # features. "side": no contact tick.
    CSV = truth_rows([(999, (9, 9, 9), (0, 0, 0), 1, 0), (1000, (3, 4, 6), (0, 0, 6), 1, 1),
                      (1500, (7, 7, 7), (0, 0, 0), 0, 0), (2000, (0, 0, 8), (0, 0, 8), 0, 1),
                      (2500, (5, 0, 0), (0, 0, 0), 1, 0), (3000, (0, 0, 0), (0, 0, 0), 0, 0)])

    def test_features_come_from_the_route_and_errors_from_the_contact_ticks(self):
        r = rt.read_route(ROUTE)
        self.assertEqual(r["features"], [("top", 1.0, 2.0), ("side", 3.0, 3.5)])
        self.assertEqual(r["start"], [0.5, 2.0, 0.0])
        errs = rt.feature_errors(self.CSV, r["features"])
        self.assertAlmostEqual(errs[0][0], math.sqrt(25 / 2))
        self.assertEqual(errs[0][1:], (8.0, 2))
        self.assertEqual(errs[1], (None, 0.0, 0))
        lines = rt.explore3d_features_table(r, [("0 ms", self.CSV)]).splitlines()
        self.assertEqual(lines[0], "| run | top | side |")
        self.assertEqual(lines[2], "| 0 ms | 3.54 of 8.0 (44 %), 2 | no contact |")

    def test_the_table_has_a_row_per_feature_and_scene_and_a_column_per_round_trip_and_variant(self):
        d = tempfile.mkdtemp(prefix="hemm-report-tables-")
        for v in ("a", "b"):
            os.makedirs(os.path.join(d, v, "0ms"))
            open(os.path.join(d, v, "route.txt"), "w").write(ROUTE)
            open(os.path.join(d, v, "0ms", "truth.csv"), "w").write(self.CSV)
            json.dump({"contact_ticks": 4, "force_rms_n": 1.5, "true_force_peak_n": 10.0},
                      open(os.path.join(d, v, "0ms", "truth.json"), "w"))
        t = rt.explore3d_table([("table", "camera fixed", "0", os.path.join(d, "a")),
                                ("table", "camera active", "0", os.path.join(d, "b"))]).splitlines()
        self.assertEqual(t[0], "| scene | feature | 0 ms, camera fixed | 0 ms, camera active |")
        self.assertEqual(t[2], "| table | top | 3.54 of 8.0 (44 %) | 3.54 of 8.0 (44 %) |")
        self.assertEqual(t[3], "| table | side | no contact | no contact |")
        self.assertEqual(t[4], "| table | whole run | 1.50 of 10.0 (15 %) | 1.50 of 10.0 (15 %) |")
        self.assertEqual(len(t), 5)
        # A missing run, a route that is not one, a CSV of something else: refused, naming the file.
        with self.assertRaisesRegex(rt.InputError, "nope/route.txt"):
            rt.explore3d_table([("table", "x", "0", os.path.join(d, "nope"))])
        with self.assertRaisesRegex(rt.InputError, r"route:2: not a route line"):
            rt.read_route("scene s\nfeature top 1\n")
        with self.assertRaisesRegex(rt.InputError, "no features"):
            rt.read_route("scene s\nroute r\nstart 0 0 0\nregion 0 0 0 1 1 1\nend 2\n")
        with self.assertRaisesRegex(rt.InputError, "not hemm-truth --tool6 --csv output"):
            rt.feature_errors("a,b\n1,2\n", [("top", 0, 1)])
        with self.assertRaisesRegex(rt.InputError, "truth.csv:3: 3 columns"):
            rt.feature_errors(TRUTH_HEAD + "1,0,0,0,0,0,0,0,0,0\n1,2,3\n", [("top", 0, 1)])


if __name__ == "__main__":
    unittest.main()
