// SIMULATION ONLY: the ground truth of the 3-DoF point probe (the SIMULATED
// Omni, probe_3d.tool "point", common/haptics/vps/point_probe.h) on the live
// voxmap (issue 24 part 4). The device point the servo logged per tick
// (world log goal_x.., the probe's goal in W) is replayed with the same
// point-probe contact model and parameters (probe radius, force law, scale:
// the operator config's) against the exact voxelisation of the scene's MJCF
// geometry in a region (tool6_truth.h build_truth_voxmap, the same truth the
// 6-DoF tool is measured against): the force the same hand path would get
// from the true scene, against what the live model gave.
#pragma once

#include <cstdint>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/haptics/vps/point_probe.h"

namespace hemm::robot {

// Opens a CSV log and reads its header: *col the index of each column by
// name; false with *error ("cannot read PATH", or "PATH: no column N
// (not WHAT?)") if the file or one of `need` is missing.
bool open_world_log_columns(const std::string& path, const std::vector<const char*>& need, const char* what,
                            std::ifstream* in, std::map<std::string, std::size_t>* col, std::string* error);

// One servo tick of the world log.
struct Probe3Tick {
  double t_s = 0.0;  // from the first row
  Eigen::Vector3d goal_W = Eigen::Vector3d::Zero();   // the device point in W
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();  // displayed (live, after the gain), device N
  Eigen::Vector3d proxy_W = Eigen::Vector3d::Zero();  // the live proxy
  double gain = 1.0;
  bool contact = false;  // the live probe touched
  bool exploring = true; // wire mode exploration (the probe runs only then)
  bool model = true;     // the live tick had a model snapshot
};

// The columns of the world log (hemm-operator --log RUN.csv writes
// RUN.csv.world.csv) the replay needs, by name; false with *error (the file,
// and the line of a short or non-numeric row) and *out untouched otherwise;
// a last line without its newline (a killed writer) is dropped.
bool read_probe3_world_log(const std::string& path, std::vector<Probe3Tick>* out, std::string* error);

struct Probe3Truth {
  std::vector<Eigen::Vector3d> force_W, proxy_W;  // per tick: the true displayed force, the true proxy
  std::vector<std::uint8_t> contact;              // per tick: the true probe touched
  std::size_t contact_ticks = 0;                  // the live or the true probe touched
  double force_rms = 0, force_max = 0;            // |live - true| over the contact ticks
  double true_force_peak = 0;
};

// Replays the ticks against vm with params p at `scale` (W m per device m):
// the probe reset to the first exploring tick's goal, then one
// point_probe_tick per exploring tick (no voxmap where the live tick had no
// model, as live); the gain of each tick on the true force.
Probe3Truth evaluate_probe3(const std::vector<Probe3Tick>& ticks, const vps::PointProbeParams& p, double scale,
                            const vps::Voxmap& vm);

}  // namespace hemm::robot
