// The data directory lookup (common/config/data_dir.h): its order, and that
// a file is found in the first directory holding it.
#include "common/config/data_dir.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace hc = hemm::config;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("hemm_data_dir_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void touch(const fs::path& p) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << "x\n";
}

TEST(DataDir, OrderIsEnvironmentInstalledTreeSourceTreeThenPrefix) {
  const fs::path root = fresh_dir("order");
  fs::create_directories(root / "build/bin");
  hc::DataDirInputs in;
  in.env = "/env/data";
  in.executable = (root / "build/bin/hemm-robot").string();
  in.build_bin_dir = (root / "build/bin").string();
  in.source_data_dir = "/src/deploy";
  in.install_data_dir = "/usr/local/share/hemm";
  EXPECT_EQ(hc::data_dir_candidates(in),
            (std::vector<std::string>{"/env/data", (root / "build/share/hemm").string(), "/src/deploy",
                                      "/usr/local/share/hemm"}));
  // Not in the build tree (an installed binary): no source tree.
  in.env.clear();
  in.executable = "/opt/hemm/bin/hemm-robot";
  EXPECT_EQ(hc::data_dir_candidates(in),
            (std::vector<std::string>{"/opt/hemm/share/hemm", "/usr/local/share/hemm"}));
  fs::remove_all(root);
}

TEST(DataDir, FirstDirectoryHoldingTheFileWins) {
  const fs::path root = fresh_dir("find");
  fs::create_directories(root / "build/bin");
  touch(root / "src/deploy/configs/robot.pbtxt");
  touch(root / "prefix/share/hemm/configs/robot.pbtxt");
  touch(root / "prefix/share/hemm/configs/operator.pbtxt");
  hc::DataDirInputs in;
  in.executable = (root / "build/bin/hemm-robot").string();
  in.build_bin_dir = (root / "build/bin").string();
  in.source_data_dir = (root / "src/deploy").string();
  in.install_data_dir = (root / "prefix/share/hemm").string();
  // A build-tree run sees the source tree before an installed copy.
  EXPECT_EQ(hc::find_data_file("configs/robot.pbtxt", in), (root / "src/deploy/configs/robot.pbtxt").string());
  // What only the prefix has comes from there.
  EXPECT_EQ(hc::find_data_file("configs/operator.pbtxt", in),
            (root / "prefix/share/hemm/configs/operator.pbtxt").string());
  EXPECT_EQ(hc::find_data_file("configs/none.pbtxt", in), "");
  // An installed tree next to the executable wins over both.
  touch(root / "opt/share/hemm/configs/robot.pbtxt");
  fs::create_directories(root / "opt/bin");
  in.executable = (root / "opt/bin/hemm-robot").string();
  EXPECT_EQ(hc::find_data_file("configs/robot.pbtxt", in), (root / "opt/share/hemm/configs/robot.pbtxt").string());
  // A directory of that name is not a file.
  fs::create_directories(root / "opt/share/hemm/configs/dir.pbtxt");
  EXPECT_EQ(hc::find_data_file("configs/dir.pbtxt", in), "");
  fs::remove_all(root);
}

TEST(DataDir, ThisTestFindsTheSourceTreesConfigs) {
  // The test binaries run from <build>/bin: the source tree's deploy/.
  if (std::getenv("HEMM_DATA_DIR") != nullptr) GTEST_SKIP() << "HEMM_DATA_DIR is set";
  EXPECT_EQ(hc::default_config_path("robot.pbtxt"),
            (fs::path(HEMM_SOURCE_DIR) / "deploy/configs/robot.pbtxt").lexically_normal().string());
}

}  // namespace
