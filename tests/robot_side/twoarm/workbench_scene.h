// The shipped two-arm scene, for the two-arm tests.
#pragma once

#include <string>

namespace hemm::test {

inline std::string workbench_scene() { return std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/workbench.xml"; }
// One definition for every test file of a target (unity builds join them).
inline const std::string kWorkbenchScene = workbench_scene();

}  // namespace hemm::test
