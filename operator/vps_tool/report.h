// The speed-against-error report of the VPS engine on a large static scene
// (>= 1 M triangles) with two tools (~25 k and ~35 k triangles), side by side
// with FCL mesh-mesh collision on the same poses. Used by `hemm-vps report`.
#pragma once

#include <cstdio>
#include <string>

namespace hemm::vps_tool {

struct ReportOptions {
  double scene_voxel = 0.003;   // m
  double shell_voxel = 0.002;   // m (tool pointshells and the left tool's voxmap)
  int ticks = 2000;             // trajectory length (1 kHz ticks)
  int repeats = 3;              // timing passes over the trajectory
  int fcl_every = 10;           // FCL on every n-th pose (0: skip FCL)
  int spheres_per_side = 7;     // generated scene: n x n icospheres of 20480 triangles
  std::string scene_file;       // optional mesh file instead of the generated scene (no force error then)
};

// Runs the report, printing tables to `out`. Returns 0 on success, 1 on error
// (message printed).
int run_report(const ReportOptions& options, std::FILE* out);

}  // namespace hemm::vps_tool
