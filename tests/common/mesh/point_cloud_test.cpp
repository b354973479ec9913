// PCD point clouds through PCL into validated points.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "common/mesh/point_cloud.h"

namespace hemm::mesh {
namespace {

TEST(PointCloud, LoadsPcdDropsNanAndRejectsBadFiles) {
  const auto dir = std::filesystem::temp_directory_path() / ("hemm_pcd_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string ok = (dir / "ok.pcd").string();
  {
    std::ofstream f(ok);
    f << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4\nHEIGHT 1\n"
         "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n0 0 0\n1 0 0\nnan nan nan\n0 2 0.5\n";
  }
  std::vector<Eigen::Vector3d> pts;
  std::size_t dropped = 0;
  ASSERT_FALSE(load_point_cloud_pcd(ok, {}, &pts, &dropped));
  ASSERT_EQ(pts.size(), 3u);
  EXPECT_EQ(dropped, 1u);
  EXPECT_NEAR((pts[2] - Eigen::Vector3d(0, 2, 0.5)).norm(), 0.0, 1e-6);
  std::vector<Eigen::Vector3d> untouched = {{9, 9, 9}};
  EXPECT_TRUE(load_point_cloud_pcd((dir / "missing.pcd").string(), {}, &untouched, nullptr));
  {
    std::ofstream f(dir / "bad.pcd");
    f << "not a pcd\n";
  }
  EXPECT_TRUE(load_point_cloud_pcd((dir / "bad.pcd").string(), {}, &untouched, nullptr));
  PointCloudLimits small;
  small.max_extent = 1.0;
  EXPECT_TRUE(load_point_cloud_pcd(ok, small, &untouched, nullptr));
  EXPECT_EQ(untouched.size(), 1u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hemm::mesh
