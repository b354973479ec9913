// The live voxmap's region of interest around the probe (voxmap_roi.h): a
// cube centred on the probe, kept while the probe stays `margin` inside it,
// re-centred when it comes nearer to a face; bad params and positions.
#include "common/mapping/voxmap_roi.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace hm = hemm::mapping;

namespace {

bool same(const Eigen::AlignedBox3d& a, const Eigen::AlignedBox3d& b) { return a.min() == b.min() && a.max() == b.max(); }

}  // namespace

TEST(ProbeRoi, CubeAroundTheProbeMovesOnlyWhenTheProbeNearsAFace) {
  const hm::ProbeRoiParams p{0.6, 0.15};
  ASSERT_FALSE(hm::check(p));
  const Eigen::Vector3d start(1.5, 1.9, 0.85);
  const auto first = hm::follow_probe(p, std::nullopt, start);
  ASSERT_TRUE(first);
  EXPECT_TRUE(first->min().isApprox(Eigen::Vector3d(1.2, 1.6, 0.55), 1e-12));
  EXPECT_TRUE(first->max().isApprox(Eigen::Vector3d(1.8, 2.2, 1.15), 1e-12));
  // Anywhere within 0.15 m of the centre along each axis (0.15 m from each
  // face): the same box, so nothing is dropped.
  for (const Eigen::Vector3d& d : {Eigen::Vector3d(0.149, 0, 0), Eigen::Vector3d(-0.149, 0.149, -0.149),
                                   Eigen::Vector3d(0, 0, 0.1499)}) {
    const auto r = hm::follow_probe(p, first, start + d);
    ASSERT_TRUE(r);
    EXPECT_TRUE(same(*r, *first)) << d.transpose();
  }
  // Nearer a face than the margin: re-centred on the probe.
  const Eigen::Vector3d near_face = start + Eigen::Vector3d(0.0, 0.16, 0.0);
  const auto moved = hm::follow_probe(p, first, near_face);
  ASSERT_TRUE(moved);
  EXPECT_TRUE(moved->center().isApprox(near_face, 1e-12));
  EXPECT_NEAR(moved->sizes().minCoeff(), 0.6, 1e-12);
  EXPECT_NEAR(moved->sizes().maxCoeff(), 0.6, 1e-12);
  // The probe was 0.14 m inside the old box's face when it moved: what lies
  // within 0.13 m of it was in the old box and is in the new one (the
  // surface the probe touches is not dropped).
  for (int c = 0; c < 8; ++c) {
    const Eigen::AlignedBox3d ball(near_face - Eigen::Vector3d::Constant(0.13), near_face + Eigen::Vector3d::Constant(0.13));
    const Eigen::Vector3d q = ball.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
    EXPECT_TRUE(moved->contains(q));
    EXPECT_TRUE(first->contains(q));
  }
  // A probe that jumped outside entirely: re-centred too.
  const auto far = hm::follow_probe(p, first, Eigen::Vector3d(5, 5, 5));
  ASSERT_TRUE(far);
  EXPECT_TRUE(far->center().isApprox(Eigen::Vector3d(5, 5, 5), 1e-12));
}

TEST(ProbeRoi, BadParamsAndPositionsChangeNothing) {
  EXPECT_TRUE(hm::check(hm::ProbeRoiParams{0.0, 0.1}));
  EXPECT_TRUE(hm::check(hm::ProbeRoiParams{0.6, 0.3}));   // margin must be below half the edge
  EXPECT_TRUE(hm::check(hm::ProbeRoiParams{0.6, 0.0}));
  EXPECT_TRUE(hm::check(hm::ProbeRoiParams{std::nan(""), 0.1}));
  const hm::ProbeRoiParams p{0.6, 0.15};
  const Eigen::Vector3d bad(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  EXPECT_FALSE(hm::follow_probe(p, std::nullopt, bad));
  const Eigen::AlignedBox3d cur(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1));
  const auto r = hm::follow_probe(p, cur, bad);
  ASSERT_TRUE(r);
  EXPECT_TRUE(same(*r, cur));
}
