// The engine report of the VPS engine (`hemm-vps report`): the assembly
// scene (a static part of over a million triangles, tools of about 25 k and
// 35 k triangles) on a scripted trajectory whose three contacts have exact
// references (pressure model closed forms), the full three-pair cycle and the
// time-critical mode at several budgets, FCL on the same poses, and a run at
// the paper's scale (3.36 M triangles). One thread; cycle times are thread
// CPU time (a shared machine preempts; CPU time is what the cycle costs).
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace hemm::vps_tool {

struct ReportOptions {
  double scene_voxel = 0.003;   // m
  double shell_voxel = 0.0025;  // m (tool pointshells and the left tool's voxmap)
  int ticks = 2000;             // trajectory length (1 kHz ticks)
  int repeats = 3;              // timing passes over the trajectory
  int fcl_every = 10;           // FCL on every n-th pose (0: skip FCL)
  int bosses = 13;              // assembly scene: 13 bosses of 81,920 triangles (1.07 M)
  int layers = 0;               // scene distance layers; 0: from the coupling's maximum expected penetration
  int paper_bosses = 41;        // paper-scale run: 41 bosses (3.36 M); 0 skips it
  std::vector<std::int64_t> budgets = {500, 1000, 2000, 4000, 8000};  // time-critical work budgets
};

// Runs the report, printing the table to `out`. Returns 0 on success, 1 on
// error (message printed).
int run_report(const ReportOptions& options, std::FILE* out);

}  // namespace hemm::vps_tool
