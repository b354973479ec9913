// The device.bimanual config block: defaults give the device the issue
// describes; bad values (out-of-range limits and gains, unknown names,
// non-finite numbers, a grip object on an arm whose handle has no grip
// lever, a plane stiffer than the device renders) are refused with
// file:line: field: message, and the output config stays untouched.
#include "operator/bimanual/bimanual_config.h"

#include <gtest/gtest.h>

namespace hb = hemm::device::bimanual;

namespace {

std::optional<hemm::config::ConfigError> parse(const std::string& text, hemm::config::OperatorConfig* out) {
  return hemm::config::parse_text_config(text, "op.pbtxt", &hemm::op::validate_operator_config_with_bimanual, out);
}

std::string error_of(const std::string& bimanual_block) {
  hemm::config::OperatorConfig c;
  c.mutable_net()->set_command_rate_hz(123);  // a marker: must survive a refused parse
  const auto e = parse("device {\n  type: \"sim-bimanual\"\n  bimanual {\n" + bimanual_block + "\n  }\n}\n", &c);
  if (e) {
    EXPECT_EQ(c.net().command_rate_hz(), 123u) << "a refused config changed the output";
  }
  return e ? e->to_string() : std::string();
}

}  // namespace

TEST(BimanualConfig, DefaultsAreThePapersDevice) {
  hemm::config::OperatorConfig c;
  ASSERT_FALSE(parse("device { type: \"sim-bimanual\" }", &c));
  const hemm::op::BimanualSetup s = hemm::op::bimanual_setup(c.device().bimanual());
  EXPECT_EQ(s.script, "features");
  for (int a = 0; a < 2; ++a) {
    const hb::ArmControlParams& p = s.sim.control[static_cast<size_t>(a)];
    EXPECT_EQ(s.sim.plant.handles[static_cast<size_t>(a)], hb::HandleKind::kMagneticClutch);
    EXPECT_DOUBLE_EQ(p.elbow_force, 20.0);
    EXPECT_DOUBLE_EQ(p.inertia_ratio_translation, 0.33);
    EXPECT_DOUBLE_EQ(p.inertia_ratio_rotation, 0.25);
    EXPECT_TRUE(p.feedforward);
    EXPECT_EQ(p.projector, hb::NullSpaceProjector::kDynamic);
  }
  EXPECT_GT(s.sim.plant.actuators.coulomb_friction.minCoeff(), 0.0);  // LWR-like, not ideal
}

TEST(BimanualConfig, ArmsAndEnvironmentFromTheBlock) {
  hemm::config::OperatorConfig c;
  ASSERT_FALSE(parse(R"(device { type: "sim-bimanual" bimanual {
      ideal_actuators: true collision_activation_m: 0.2 script: "idle"
      right { handle: "grip_force" grip_object_at_m: 0.012 null_space_projector: "kinematic" inertia_ratio_translation: 1
              inertia_ratio_rotation: 1 plane_normal_x: 1 plane_normal_z: 0 plane_stiffness_n_per_m: 2500 }
      left { handle: "joystick" elbow_force_n: 0 peak_force_n: 80 } } })",
                     &c));
  const hemm::op::BimanualSetup s = hemm::op::bimanual_setup(c.device().bimanual());
  EXPECT_EQ(s.script, "idle");
  EXPECT_EQ(s.sim.plant.handles[0], hb::HandleKind::kGripForce);
  EXPECT_EQ(s.sim.plant.handles[1], hb::HandleKind::kJoystick);
  EXPECT_EQ(s.sim.control[0].projector, hb::NullSpaceProjector::kKinematic);
  EXPECT_FALSE(s.sim.control[0].feedforward);
  EXPECT_DOUBLE_EQ(s.sim.control[1].elbow_force, 0.0);
  EXPECT_DOUBLE_EQ(s.sim.control[1].peak_force, 80.0);
  EXPECT_DOUBLE_EQ(s.sim.control[0].collision.activation_m, 0.2);
  EXPECT_TRUE(s.env[0].grip_object);
  EXPECT_DOUBLE_EQ(s.env[0].grip_object_at_m, 0.012);
  EXPECT_EQ(s.env[0].plane_normal_H, Eigen::Vector3d::UnitX());
  EXPECT_DOUBLE_EQ(s.env[0].plane_stiffness, 2500.0);
  EXPECT_FALSE(s.env[1].grip_object);
  EXPECT_EQ(s.sim.plant.actuators.coulomb_friction.maxCoeff(), 0.0);
  // The humans: relaxed, spring only, unless asked.
  EXPECT_DOUBLE_EQ(s.sim.plant.humans[0].max_voluntary_force, 0.0);
  EXPECT_DOUBLE_EQ(s.sim.plant.humans[0].arm_stiffness, hb::HumanModel{}.arm_stiffness);
  ASSERT_FALSE(parse(R"(device { type: "sim-bimanual" bimanual { human_voluntary_force_n: 12 human_co_contracting: true } })",
                     &c));
  const hemm::op::BimanualSetup h = hemm::op::bimanual_setup(c.device().bimanual());
  for (const hb::HumanModel& m : h.sim.plant.humans) {
    EXPECT_DOUBLE_EQ(m.max_voluntary_force, 12.0);
    EXPECT_DOUBLE_EQ(m.arm_stiffness, hb::co_contracting_human(0.0).arm_stiffness);
    EXPECT_DOUBLE_EQ(m.arm_rot_stiffness, hb::co_contracting_human(0.0).arm_rot_stiffness);
  }
}

TEST(BimanualConfig, BadValuesAreRefusedWithFileLineAndField) {
  EXPECT_EQ(error_of("    right { inertia_ratio_translation: 0.01 }"),
            "op.pbtxt:4:13: device.bimanual.right.inertia_ratio_translation: must be in [0.1, 1]");
  EXPECT_EQ(error_of("    left {\n      handle: \"joystick\"\n      grip_object_at_m: 0.01\n    }"),
            "op.pbtxt:6:7: device.bimanual.left.grip_object_at_m: the joystick handle has no grip");
  EXPECT_EQ(error_of("    right { handle: \"pliers\" }"),
            "op.pbtxt:4:13: device.bimanual.right.handle: must be \"magnetic_clutch\", \"grip_force\" or \"joystick\"");
  EXPECT_NE(error_of("    right { peak_force_n: 1000 }").find("right.peak_force_n: must be in (0, 300] N"), std::string::npos);
  EXPECT_NE(error_of("    right { peak_torque_nm: -1 }").find("right.peak_torque_nm"), std::string::npos);
  EXPECT_NE(error_of("    left { max_linear_speed_mps: nan }").find("left.max_linear_speed_mps"), std::string::npos);
  EXPECT_NE(error_of("    left { elbow_force_n: inf }").find("left.elbow_force_n"), std::string::npos);
  EXPECT_NE(error_of("    left { plane_stiffness_n_per_m: 20000 }").find("max_stiffness"), std::string::npos);
  EXPECT_NE(error_of("    left { plane_normal_x: 0 plane_normal_y: 0 plane_normal_z: 0 }").find("plane normal"),
            std::string::npos);
  EXPECT_NE(error_of("    right { handle: \"grip_force\" grip_object_at_m: 0.2 }").find("lever's travel"),
            std::string::npos);
  EXPECT_NE(error_of("    right { null_space_projector: \"magic\" }").find("null_space_projector"), std::string::npos);
  EXPECT_NE(error_of("    collision_activation_m: 0"), std::string());
  EXPECT_NE(error_of("    human_voluntary_force_n: 80").find("human_voluntary_force_n: must be in [0, 50] N"),
            std::string::npos);
  EXPECT_NE(error_of("    script: \"dance\"").find("script: must be one of: features, idle"), std::string::npos);
  EXPECT_NE(error_of("    right { no_such_field: 1 }").find("no_such_field"), std::string::npos);
  EXPECT_EQ(error_of(""), "");  // the defaults pass
}

TEST(BimanualConfig, OtherDevicesIgnoreTheBlock) {
  hemm::config::OperatorConfig c;
  // A bad bimanual block does not matter while the device is the Omni...
  EXPECT_FALSE(parse("device { type: \"sim-omni\" bimanual { right { peak_force_n: 1000 } } }", &c));
  // ...and an unknown device type is still refused.
  EXPECT_TRUE(parse("device { type: \"sim-octopus\" }", &c));
}
