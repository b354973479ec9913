#include "common/mapping/voxmap_roi.h"

namespace hemm::mapping {

std::optional<std::string> check(const ProbeRoiParams& p) {
  if (!(p.size >= 0.05 && p.size <= 10.0)) return "probe ROI: size not in [0.05, 10] m";
  if (!(p.margin > 0.0 && p.margin < 0.5 * p.size)) return "probe ROI: margin not in (0, size / 2)";
  return std::nullopt;
}

Eigen::AlignedBox3d roi_around(const ProbeRoiParams& p, const Eigen::Vector3d& probe_W) {
  const Eigen::Vector3d h = Eigen::Vector3d::Constant(0.5 * p.size);
  return {probe_W - h, probe_W + h};
}

std::optional<Eigen::AlignedBox3d> follow_probe(const ProbeRoiParams& p, const std::optional<Eigen::AlignedBox3d>& current,
                                                const Eigen::Vector3d& probe_W) {
  if (!probe_W.allFinite()) return current;
  if (current) {
    const Eigen::Vector3d m = Eigen::Vector3d::Constant(p.margin);
    if ((probe_W.array() >= (current->min() + m).array()).all() && (probe_W.array() <= (current->max() - m).array()).all())
      return current;
  }
  return roi_around(p, probe_W);
}

}  // namespace hemm::mapping
