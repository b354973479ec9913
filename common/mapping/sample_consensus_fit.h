#pragma once
// What the 2D and the 3D shape completion (shape_completion.cpp,
// shape_completion3d.cpp) both do with PCL's sample consensus. Includes PCL:
// include it from those .cpp files only.
#include <algorithm>
#include <numbers>
#include <vector>

#include <Eigen/Core>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>

namespace hemm::mapping {

// RANSAC (PCL; its fixed seed makes one cloud give one model) for one model,
// then a least-squares refinement on its inliers. False when no finite
// model was found.
template <typename Model>
bool ransac_refined(const typename Model::Ptr& model, double inlier_distance, int max_iterations,
                    Eigen::VectorXf& coeff) {
  pcl::RandomSampleConsensus<pcl::PointXYZ> sac(model, inlier_distance);
  sac.setMaxIterations(max_iterations);
  if (!sac.computeModel()) return false;
  pcl::Indices inliers;
  sac.getInliers(inliers);
  Eigen::VectorXf raw;
  sac.getModelCoefficients(raw);
  if (inliers.size() <= model->getSampleSize()) {
    coeff = raw;
    return raw.allFinite();
  }
  model->optimizeModelCoefficients(inliers, raw, coeff);
  return coeff.allFinite();
}

// The arc that angles (radians, sorted in place) span: 2 pi minus their largest gap.
inline double arc_spanned(std::vector<double>& ang) {
  if (ang.size() < 2) return 0.0;
  std::sort(ang.begin(), ang.end());
  double gap = ang.front() + 2.0 * std::numbers::pi - ang.back();
  for (std::size_t i = 1; i < ang.size(); ++i) gap = std::max(gap, ang[i] - ang[i - 1]);
  return 2.0 * std::numbers::pi - gap;
}

}  // namespace hemm::mapping
