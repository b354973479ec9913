// The 6-DoF probe tool on the right arm of the SIMULATED bimanual device
// (operator/station/tool6_bimanual.h): the hand6 script mapped into the
// device frame D and back through the Tool6Explorer's own mapping, and the
// checks of the path against the arm (hand_path_check.h) with clear errors
// and no change to the tool's parameters.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "config_operator.pb.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/station/tool6_bimanual.h"
#include "operator/station/tool6_explorer.h"

namespace ho = hemm::op;
namespace hb = hemm::device::bimanual;

namespace {

// The shipped config's offset (probe_3d defaults).
Eigen::Vector3d shipped_offset() {
  const hemm::config::Probe3dConfig c;
  return {c.tool_device_offset_x_m(), c.tool_device_offset_y_m(), c.tool_device_offset_z_m()};
}

// A route of home.xml's header (explore_route.h).
hemm::device::Trajectory home_route(const std::string& name, const Eigen::Vector3d& origin_R) {
  return ho::load_hand6_route(HEMM_SOURCE_DIR "/deploy/scenes/home.xml", name, origin_R,
                              hemm::device::rigid_hand_limits(1).ee[0]);
}

}  // namespace

TEST(Tool6Bimanual, RightHandFollowsTheHand6ScriptInDAndTheToolMapsItBackToH) {
  for (const char* script : {"explore-block", "explore-table"}) {
    const Eigen::Vector3d origin_R(0.85, 0.0, 0.95);
    const hemm::device::Trajectory path = home_route(script, origin_R);
    ho::Tool6Params tp;
    tp.limits.peak_force = -1.0;  // replaced by the right arm's
    const auto dev =
        ho::make_tool6_bimanual_device(hemm::config::BimanualDeviceConfig{}, path, shipped_offset(), 1e-3, &tp);
    ASSERT_NE(dev, nullptr);
    EXPECT_EQ(tp.limits.peak_force, dev->limits().ee[0].peak_force);
    EXPECT_TRUE(tp.limits.renders_torque);
    // The hand starts where it rests and reaches the path's start at the
    // lead-in's end (the script holds its start until 5 s).
    const auto rest = dev->simulation().resting_targets();
    EXPECT_EQ(dev->hand(hb::ArmSide::kRight).at(0.0).position_D, rest[0].position_D) << script;
    // From then on, at every key (and between keys) a hand at its human's
    // target puts the tool exactly on the script's pose in H:
    // T_H_D T_D_E R_E_P = T_H_P.
    double worst = 0.0;
    for (std::size_t i = 0; i + 1 < path.samples.size(); ++i) {
      if (path.samples[i].t_s < ho::kTool6LeadIn_s) continue;
      for (double u : {0.0, 0.5}) {
        const auto& a = path.samples[i];
        const auto& b = path.samples[i + 1];
        const double t = a.t_s + u * (b.t_s - a.t_s);
        Eigen::Isometry3d T_H_P_script = Eigen::Isometry3d::Identity();
        T_H_P_script.translation() = a.ee[0].position_H + u * (b.ee[0].position_H - a.ee[0].position_H);
        T_H_P_script.linear() = a.ee[0].orientation_H.slerp(u, b.ee[0].orientation_H).toRotationMatrix();
        const Eigen::Isometry3d T_D_E = hb::pose_D(dev->hand(hb::ArmSide::kRight).at(t));
        Eigen::Isometry3d T_E_P = Eigen::Isometry3d::Identity();
        T_E_P.linear() = tp.R_E_P;
        const Eigen::Isometry3d T_H_P = tp.T_H_D * T_D_E * T_E_P;
        worst = std::max(worst, (T_H_P.matrix() - T_H_P_script.matrix()).cwiseAbs().maxCoeff());
      }
    }
    EXPECT_LT(worst, 1e-9) << script;
    const Eigen::Isometry3d T_D_E_start = hb::pose_D(dev->hand(hb::ArmSide::kRight).at(ho::kTool6LeadIn_s));
    EXPECT_LT((T_D_E_start.translation() - (shipped_offset() + path.samples.front().ee[0].position_H)).norm(), 1e-12);
    // The left hand holds still where it rests.
    for (double t : {0.0, 7.0, 30.0})
      EXPECT_LT((dev->hand(hb::ArmSide::kLeft).at(t).position_D - rest[1].position_D).norm(), 1e-12);
    // The tool starts upright (as the script asks) in the resting grasp.
    EXPECT_LT((rest[0].orientation_D.toRotationMatrix() * tp.R_E_P -
               path.samples.front().ee[0].orientation_H.toRotationMatrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9);
    // The explorer accepts the mapping.
    EXPECT_NO_THROW(ho::Tool6Explorer{tp});
  }
}

TEST(Tool6Bimanual, ABadOffsetOrPathIsRefusedClearlyAndChangesNothing) {
  const Eigen::Vector3d origin_R(0.85, 0.0, 0.95);
  const hemm::device::Trajectory path = home_route("explore-block", origin_R);
  ho::Tool6Params tp;
  const ho::Tool6Params before = tp;
  auto unchanged = [&] {
    EXPECT_TRUE(tp.T_H_D.isApprox(before.T_H_D, 0.0));
    EXPECT_EQ(tp.R_E_P, before.R_E_P);
    EXPECT_EQ(tp.limits.peak_force, before.limits.peak_force);
    EXPECT_EQ(tp.limits.max_stiffness, before.limits.max_stiffness);
  };
  auto error = [&](const hemm::device::Trajectory& p, const Eigen::Vector3d& offset) -> std::string {
    try {
      (void)ho::make_tool6_bimanual_device(hemm::config::BimanualDeviceConfig{}, p, offset, 1e-3, &tp);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return {};
  };
  // An offset 0.3 m lower: the path drops below the workspace (and into the table's zone).
  const std::string e1 = error(path, shipped_offset() + Eigen::Vector3d(0.0, 0.0, -0.3));
  EXPECT_EQ(e1.rfind("probe_3d.tool_device_offset_x_m: the path leaves the SIMULATED right arm's workspace at t = ", 0),
            0u)
      << e1;
  unchanged();
  // 0.25 m nearer the operator: beyond the arm's reach or its stretched elbow.
  const std::string e2 = error(path, shipped_offset() + Eigen::Vector3d(-0.25, 0.0, 0.0));
  EXPECT_EQ(e2.rfind("probe_3d.tool_device_offset_x_m: the path ", 0), 0u) << e2;
  EXPECT_NE(e2.find("stall short of it; move the path (the offset) where the right arm reaches it"), std::string::npos)
      << e2;
  unchanged();
  // A script that does not hold its start through the lead-in.
  hemm::device::Trajectory early = path;
  early.samples[1].ee[0].position_H.z() -= 0.01;
  EXPECT_NE(error(early, shipped_offset()).find("hold its start"), std::string::npos);
  unchanged();
  // A non-finite offset and a path without orientations.
  EXPECT_NE(error(path, Eigen::Vector3d(NAN, 0, 0)).find("must be finite"), std::string::npos);
  hemm::device::Trajectory flat = path;
  flat.has_orientation = false;
  EXPECT_NE(error(flat, shipped_offset()).find("one end-effector with orientations"), std::string::npos);
  unchanged();
}

