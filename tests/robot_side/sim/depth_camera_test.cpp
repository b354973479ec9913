// The SIMULATED depth camera, cast through MuJoCo's mj_ray, against
// closed-form geometry: a tilted camera over the ground plane (range
// h / -d_z) and a sphere in front of the camera (ray-sphere roots); noise
// statistics, dropout rate, range limits, edge (flying pixel) dropouts.
#include "robot_side/sim/depth_camera.h"

#include <cmath>
#include <fstream>
#include <memory>
#include <numbers>

#include <gtest/gtest.h>

#include "common/sim/mujoco_owner.h"
#include "robot_side/sim/mujoco_ray_caster.h"
#include "tests/temp_dir.h"

namespace hr = hemm::robot;
namespace hm = hemm::mapping;

namespace {

struct Sim {
  hemm::sim::MujocoOwner mj;  // throws (failing the test) if the scene does not load
  mjModel* m = nullptr;
  mjData* d = nullptr;
  explicit Sim(const std::string& body) {
    static const std::string dir = hemm::test::make_temp_dir();  // one per test process
    const std::string path = dir + "/depth_camera_test.xml";
    std::ofstream(path) << "<mujoco><worldbody>" << body << "</worldbody></mujoco>";
    mj = hemm::sim::MujocoOwner::from_file(path);
    m = mj.m();
    d = mj.d();
    mj_forward(m, d);
  }
};

// Camera at height h looking down at the floor, pitched `tilt` from vertical
// about its x axis (so the image's top rows look further away).
Eigen::Isometry3d camera_over_floor(double h, double tilt) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  // Optical z down (-z_W), x along x_W, y along -y_W ... then tilt about x_S.
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  T.linear() = R * Eigen::AngleAxisd(tilt, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T.translation() << 0.3, -0.2, h;
  return T;
}

hr::SimDepthCameraParams noiseless() {
  hr::SimDepthCameraParams p;
  p.sigma_0 = p.sigma_2 = 0.0;
  p.dropout_probability = 0.0;
  p.edge_jump_fraction = 0.0;
  return p;
}

}  // namespace

TEST(DepthCamera, PlaneDepthMatchesClosedForm) {
  Sim sim(R"(<geom type="plane" size="0 0 1"/>)");
  hr::MujocoRayCaster caster(sim.m, sim.d);
  auto p = noiseless();
  p.range_max = 4.0;
  const double h = 1.1, tilt = 1.0;  // 57 deg: the top rows reach beyond range_max
  const Eigen::Isometry3d T_W_S = camera_over_floor(h, tilt);
  std::mt19937_64 rng(5);
  const hm::DepthImage img = hr::simulate_depth_image(p, caster, T_W_S, rng);
  ASSERT_EQ(img.depth.size(), 80u * 60u);
  int valid = 0, none = 0;
  for (int v = 0; v < img.K.height; ++v) {
    for (int u = 0; u < img.K.width; ++u) {
      const auto i = static_cast<std::size_t>(v * img.K.width + u);
      const Eigen::Vector3d ray_S = hm::pixel_ray_z1(img.K, u, v);
      const Eigen::Vector3d d_W = T_W_S.linear() * ray_S.normalized();
      const double r = d_W.z() < 0 ? h / -d_W.z() : -1.0;
      if (r > 0 && r <= p.range_max) {
        ASSERT_EQ(img.status[i], hm::DepthStatus::kValid) << u << "," << v;
        EXPECT_NEAR(img.depth[i], r / ray_S.norm(), 2e-6 * r);
        // The unprojected point lies on the floor.
        EXPECT_NEAR((T_W_S * (img.depth[i] * ray_S)).z(), 0.0, 2e-6);
        ++valid;
      } else {
        EXPECT_EQ(img.status[i], hm::DepthStatus::kNoReturn) << u << "," << v;
        ++none;
      }
    }
  }
  EXPECT_GT(valid, 2000);
  EXPECT_GT(none, 80);  // the tilt puts the far rows out of range
}

TEST(DepthCamera, SphereHitsAndSilhouetteMatchClosedForm) {
  // A sphere 1.2 m ahead of the camera, and a robot-group geom in front of
  // the camera that the sensor must not see.
  const Eigen::Vector3d c(1.2, 0.1, 0.5);
  const double R = 0.25;
  Sim sim(R"(<geom type="sphere" size="0.25" pos="1.2 0.1 0.5"/>
             <geom type="box" size="0.02 0.02 0.02" pos="0.3 0 0.5" group="3"/>)");
  hr::MujocoRayCaster caster(sim.m, sim.d);
  auto p = noiseless();
  p.edge_jump_fraction = 0.05;
  Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();
  // Optical z along +x_W, x_S along -y_W, y_S along -z_W.
  T_W_S.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_W_S.translation() << 0.0, 0.0, 0.5;
  std::mt19937_64 rng(7);
  const hm::DepthImage img = hr::simulate_depth_image(p, caster, T_W_S, rng);
  const Eigen::Vector3d o = T_W_S.translation();
  auto hit = [&](int u, int v) {
    const Eigen::Vector3d d = T_W_S.linear() * hm::pixel_ray_z1(img.K, u, v).normalized();
    const double b = d.dot(c - o), disc = b * b - ((c - o).squaredNorm() - R * R);
    return disc >= 0 ? b - std::sqrt(disc) : -1.0;
  };
  int hits = 0, interior_checked = 0, edge_dropped = 0;
  for (int v = 0; v < img.K.height; ++v) {
    for (int u = 0; u < img.K.width; ++u) {
      const auto i = static_cast<std::size_t>(v * img.K.width + u);
      const double r = hit(u, v);
      if (r < 0) {
        EXPECT_EQ(img.status[i], hm::DepthStatus::kNoReturn);
        continue;
      }
      ++hits;
      bool next_to_miss = false;
      for (auto [du, dv] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int uu = u + du, vv = v + dv;
        if (uu >= 0 && vv >= 0 && uu < img.K.width && vv < img.K.height && hit(uu, vv) < 0) next_to_miss = true;
      }
      if (next_to_miss) {
        // The silhouette is a flying-pixel edge: dropped, never a point in mid-air.
        EXPECT_EQ(img.status[i], hm::DepthStatus::kDropout);
        ++edge_dropped;
        continue;
      }
      const Eigen::Vector3d ray_S = hm::pixel_ray_z1(img.K, u, v);
      double slope = 0.0;
      for (auto [du, dv] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) slope = std::max(slope, std::abs(hit(u + du, v + dv) - r) / r);
      if (slope > 0.045) continue;  // grazing rim: the edge test may take it, either is right
      ASSERT_EQ(img.status[i], hm::DepthStatus::kValid) << u << "," << v;
      const Eigen::Vector3d x_W = T_W_S * (img.depth[i] * ray_S);
      EXPECT_NEAR((x_W - c).norm(), R, 1e-5);
      ++interior_checked;
    }
  }
  // 0.25 m at 1.2 m subtends ~24 degrees: a disc about 31 pixels across.
  EXPECT_GT(hits, 600);
  EXPECT_GT(interior_checked, 400);
  EXPECT_GT(edge_dropped, 60);
}

TEST(DepthCamera, NoiseGrowsWithRangeAndDropoutsHaveTheirRate) {
  Sim sim(R"(<geom type="plane" size="0 0 1"/>)");
  hr::MujocoRayCaster caster(sim.m, sim.d);
  hr::SimDepthCameraParams p;  // shipped noise model
  p.edge_jump_fraction = 0.0;
  p.dropout_probability = 0.05;
  std::mt19937_64 rng(11);
  for (const double h : {0.8, 2.0}) {
    const Eigen::Isometry3d T_W_S = camera_over_floor(h, 0.0);
    double sum = 0, sum2 = 0, sig2 = 0;
    int n = 0, dropped = 0, total = 0;
    for (int frame = 0; frame < 4; ++frame) {
      const hm::DepthImage img = hr::simulate_depth_image(p, caster, T_W_S, rng);
      for (int v = 0; v < img.K.height; ++v) {
        for (int u = 0; u < img.K.width; ++u) {
          const auto i = static_cast<std::size_t>(v * img.K.width + u);
          ++total;
          if (img.status[i] != hm::DepthStatus::kValid) {
            ++dropped;
            continue;
          }
          const Eigen::Vector3d ray = hm::pixel_ray_z1(img.K, u, v);
          const double r_true = h * ray.norm(), r_meas = img.depth[i] * ray.norm();
          const double e = (r_meas - r_true) / (p.sigma_0 + p.sigma_2 * r_true * r_true);
          sum += e;
          sum2 += e * e;
          ++n;
          sig2 += 1.0;
        }
      }
    }
    // Normalised error: mean 0, variance 1 (19200 samples: 5 sigma bounds).
    EXPECT_NEAR(sum / n, 0.0, 5.0 / std::sqrt(n)) << h;
    EXPECT_NEAR(sum2 / sig2, 1.0, 5.0 * std::sqrt(2.0 / n)) << h;
    const double rate = static_cast<double>(dropped) / total;
    EXPECT_NEAR(rate, p.dropout_probability, 5.0 * std::sqrt(0.05 * 0.95 / total)) << h;
  }
}

TEST(DepthCamera, RangeMinDropsNearReturns) {
  Sim sim(R"(<geom type="plane" size="0 0 1"/>)");
  hr::MujocoRayCaster caster(sim.m, sim.d);
  auto p = noiseless();
  std::mt19937_64 rng(3);
  const hm::DepthImage img = hr::simulate_depth_image(p, caster, camera_over_floor(0.15, 0.0), rng);
  for (const auto s : img.status) EXPECT_EQ(s, hm::DepthStatus::kDropout);  // too near says nothing
}

TEST(DepthCamera, ParamsAreValidated) {
  hr::SimDepthCameraParams p;
  EXPECT_FALSE(hr::check_params(p));
  auto bad = p;
  bad.width = 0;
  EXPECT_TRUE(hr::check_params(bad));
  bad = p;
  bad.range_min = 3.5;
  EXPECT_TRUE(hr::check_params(bad));
  bad = p;
  bad.hfov = std::numbers::pi;
  EXPECT_TRUE(hr::check_params(bad));
  bad = p;
  bad.dropout_probability = 1.5;
  EXPECT_TRUE(hr::check_params(bad));
  bad = p;
  bad.sigma_0 = std::nan("");
  EXPECT_TRUE(hr::check_params(bad));
}
