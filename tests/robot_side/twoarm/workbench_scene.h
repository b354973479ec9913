// The shipped two-arm scene, for the two-arm tests.
#pragma once

#include <string>

namespace hemm::test {

inline std::string workbench_scene() { return std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/workbench.xml"; }
// The box with both hands: the box and the shelf within both arms' reach.
inline std::string workbench_box_scene() { return std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/workbench_box.xml"; }
// One definition for every test file of a target (unity builds join them).
inline const std::string kWorkbenchScene = workbench_scene();

}  // namespace hemm::test
