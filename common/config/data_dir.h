// Where hemm finds the data it ships (configs/, scenes/, meshes/, the demo
// key): one lookup for every binary, so an installed hemm-robot or
// hemm-operator runs without a path (docs/install.md).
//
// The data directory is the first of these that exists:
//   1. $HEMM_DATA_DIR, when set (a user's own copy);
//   2. <directory of the executable>/../share/hemm: an installed tree, where
//      it was installed (cmake --install --prefix P, the Debian package);
//   3. the source tree's deploy/, when the executable runs from the build
//      tree it was built in (<build>/bin): a developer's run sees the
//      files being edited, never an older installed copy;
//   4. the compiled-in install prefix's share/hemm (an installed binary
//      copied elsewhere).
// Paths inside a config stay relative to that config file
// (config::resolve_relative_to), so a config found here finds its scene and
// key beside it.
#pragma once

#include <string>
#include <vector>

namespace hemm::config {

// What the lookup depends on, so its order can be tested without installing.
struct DataDirInputs {
  std::string env;             // $HEMM_DATA_DIR ("" : unset)
  std::string executable;      // the running executable's path ("" : unknown)
  std::string build_bin_dir;   // <build>/bin of the build that made it
  std::string source_data_dir; // <source>/deploy
  std::string install_data_dir;  // <prefix>/share/hemm
};

// The candidate directories in lookup order (existing or not).
std::vector<std::string> data_dir_candidates(const DataDirInputs& in);
// This process's inputs: the environment, /proc/self/exe and the compiled-in
// directories.
DataDirInputs this_process_data_dir_inputs();

// The first candidate that holds `relative` (e.g. "configs/robot.pbtxt"):
// the file's full path, or "" if none does.
std::string find_data_file(const std::string& relative, const DataDirInputs& in);
std::string find_data_file(const std::string& relative);

// A station's default config (`name` in configs/ of the data directory), or
// "" if there is none; `searched` (if given) gets the directories looked in,
// for the error message.
std::string default_config_path(const std::string& name, std::vector<std::string>* searched = nullptr);

}  // namespace hemm::config
