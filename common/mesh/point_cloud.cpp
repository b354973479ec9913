#include "common/mesh/point_cloud.h"

#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <filesystem>

namespace hemm::mesh {

std::optional<MeshError> load_point_cloud_pcd(const std::string& path, const PointCloudLimits& limits,
                                              std::vector<Eigen::Vector3d>* out, std::size_t* dropped) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return MeshError{path + ": no such file"};
  pcl::PCDReader reader;
  {
    // PCL's reader can crash on a malformed file whose header it rejected:
    // check the header first (x, y, z fields and a positive point count).
    pcl::PCLPointCloud2 header;
    Eigen::Vector4f origin;
    Eigen::Quaternionf orientation;
    int version = 0, data_type = 0;
    unsigned int data_idx = 0;
    if (reader.readHeader(path, header, origin, orientation, version, data_type, data_idx) != 0)
      return MeshError{path + ": not a valid PCD header"};
    bool x = false, y = false, z = false;
    for (const auto& f : header.fields) {
      x = x || f.name == "x";
      y = y || f.name == "y";
      z = z || f.name == "z";
    }
    if (!x || !y || !z) return MeshError{path + ": PCD file has no x, y, z fields"};
    if (static_cast<std::uint64_t>(header.width) * header.height == 0) return MeshError{path + ": PCD file has no points"};
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (reader.read(path, cloud) != 0) return MeshError{path + ": cannot read PCD file"};
  if (cloud.size() > limits.max_points) return MeshError{path + ": too many points"};
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(cloud.size());
  std::size_t nan = 0;
  Eigen::AlignedBox3d box;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const auto& p = cloud[i];
    if (std::isnan(p.x) || std::isnan(p.y) || std::isnan(p.z)) {
      ++nan;
      continue;
    }
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return MeshError{path + ": point " + std::to_string(i) + " has an infinite coordinate"};
    pts.emplace_back(p.x, p.y, p.z);
    box.extend(pts.back());
  }
  if (pts.empty()) return MeshError{path + ": no valid points"};
  if (!(box.sizes().maxCoeff() <= limits.max_extent)) return MeshError{path + ": extent exceeds the limit (wrong units?)"};
  *out = std::move(pts);
  if (dropped != nullptr) *dropped = nan;
  return std::nullopt;
}

}  // namespace hemm::mesh
