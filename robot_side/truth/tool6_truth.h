// SIMULATION ONLY: the ground truth of the 6-DoF tool on the live voxmap
// (operator/station/tool6_explorer.h, issue 13). The scene's static geometry
// in a region (load_scene_meshes: table top, legs, block, book, mug) is
// voxelised exactly at 2.5 mm, and the hand's goal path the servo logged
// (world log: goal_x.., goal_q..) is replayed with the same tool, contact and
// coupling (vps::replay_tool_path): the displayed force and torque the same
// hand path would get from the true scene, against what the live model gave.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/haptics/vps/probe_tool.h"

namespace hemm::robot {

// One servo tick of the world log.
struct Tool6Tick {
  double t_s = 0.0;           // from the first row
  Eigen::Isometry3d goal = Eigen::Isometry3d::Identity();
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();  // displayed (live)
  Eigen::Vector3d tool = Eigen::Vector3d::Zero();
  double gain = 1.0;
  int contacts = 0;
  int mode = 0;
  bool model = true;          // the live tick had a voxmap
};
// Reads hemm-operator's <log>.world.csv; false with *error on a missing
// column or an unreadable file.
bool read_tool6_world_log(const std::string& path, std::vector<Tool6Tick>* out, std::string* error);

// The tool and its parameters as the station wrote them (<log>.tool6.txt:
// key value lines, tool6_explorer.h write_tool6_params).
bool read_tool6_params(const std::string& path, vps::ProbeToolGeometry* geometry, vps::ToolParams* params,
                       std::string* error);

// The true scene inside region_W as one voxmap (voxel size s, 8 layers each way).
bool build_truth_voxmap(const std::string& scene, const Eigen::AlignedBox3d& region_W, double s, vps::Voxmap* out,
                        std::vector<std::string>* parts, std::string* error);

struct Tool6Truth {
  vps::ToolReplay replay;  // per tick: the true displayed wrench
  std::size_t contact_ticks = 0;  // ticks where the live or the true tool touches
  double force_rms = 0, force_max = 0, torque_rms = 0, torque_max = 0;  // |live - true| over contact ticks
  double true_force_peak = 0, true_torque_peak = 0;
};
// Replays the ticks (mode exploration only: others keep zero) against vm.
Tool6Truth evaluate_tool6(const std::vector<Tool6Tick>& ticks, const vps::ProbeTool& tool,
                          const vps::ToolParams& params, const vps::Voxmap& vm);

}  // namespace hemm::robot
