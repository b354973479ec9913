// Where the two-arm station's task objects are, as the operator knows it
// before the session (issue 25, part 6): the `task:` lines in the header of
// the scene file (deploy/scenes/workbench.xml), not the simulation's truth
// at run time. One line per object, numbers in A (metres):
//
//   task: box   centre X Y Z  size SX SY SZ
//   task: shelf place X Y Z                  (the board's top centre)
//   task: peg   centre X Y Z  half H  length L     (square: H half its width, flats along x, y)
//   task: hole  top X Y Z     depth D        (the hole's top centre, axis +z)
//   task: bar   centre X Y Z  radius R  length L   (its axis along y)
//
// Each object once, every key once; anything else is an error naming
// file:line and the reason, and no scene is returned.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

namespace hemm::twoarm_tasks {

struct TaskScene {
  Eigen::Vector3d box_centre = Eigen::Vector3d::Zero(), box_size = Eigen::Vector3d::Zero();
  Eigen::Vector3d shelf_place = Eigen::Vector3d::Zero();
  Eigen::Vector3d peg_centre = Eigen::Vector3d::Zero();
  double peg_half_width_m = 0.0, peg_length_m = 0.0;
  Eigen::Vector3d hole_top = Eigen::Vector3d::Zero();
  double hole_depth_m = 0.0;
  Eigen::Vector3d bar_centre = Eigen::Vector3d::Zero();
  double bar_radius_m = 0.0, bar_length_m = 0.0;
};

struct TaskSceneResult {
  std::optional<TaskScene> scene;
  std::string error;  // "file:line: reason" (or "file: reason") when no scene
};

// `file` names the text in the errors.
TaskSceneResult parse_task_scene(const std::string& text, const std::string& file);
// Reads the file; an unreadable file is an error too.
TaskSceneResult load_task_scene(const std::string& path);

}  // namespace hemm::twoarm_tasks
