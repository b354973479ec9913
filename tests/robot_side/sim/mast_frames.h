#pragma once
// Test and benchmark helper: the SIMULATED robot standing before the home
// scene's table (W (1.5, 1.0), facing +y) with its SIMULATED mast depth
// camera, its frames cut into DepthChunks and decoded as the operator
// receives them (newest cloud wins).
#include <numbers>
#include <string>
#include <vector>

#include "common/mapping/depth_stream.h"
#include "config_robot.pb.h"
#include "robot_side/sim/simulated_robot.h"

namespace hemm::test {

inline const std::string kHomeScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

inline hemm::config::RobotConfig robot_before_the_table() {
  hemm::config::RobotConfig c;
  c.mutable_sim()->set_start_x_m(1.5);
  c.mutable_sim()->set_start_y_m(1.0);
  c.mutable_sim()->set_start_theta_rad(std::numbers::pi / 2);
  c.mutable_depth_camera()->set_enabled(true);
  return c;
}

struct MastChunk {
  double t_s = 0.0;  // simulation time the frame was taken out (the step it came with)
  mapping::DepthChunkData chunk;
};

// Steps the simulation `steps` ms and appends every frame's chunks to *out.
// A reason on failure.
inline std::optional<std::string> simulate_mast_chunks(int steps, std::vector<MastChunk>* out) {
  const hemm::config::RobotConfig cfg = robot_before_the_table();
  robot::SimulatedRobot robot;
  if (auto e = robot.load(cfg, kHomeScene)) return "load: " + *e;
  if (auto e = robot.enable_depth_camera(robot::depth_camera_params_from_config(cfg))) return "camera: " + *e;
  mapping::DepthStreamReceiver rx;
  for (int i = 0; i < steps; ++i) {
    robot.step(1);
    for (const mapping::DepthImage& img : robot.take_depth_images()) {
      std::vector<hemm::wire::DepthChunk> wire;
      if (auto e = mapping::encode_depth_chunks(img, "depth", mapping::DepthStreamParams{}, &wire)) return "encode: " + *e;
      for (const auto& c : wire) {
        MastChunk m;
        m.t_s = (i + 1) * 1e-3;
        if (rx.receive(c, 0, &m.chunk) != mapping::DepthStreamReceiver::Verdict::kAccepted) return "chunk not accepted";
        out->push_back(std::move(m));
      }
    }
  }
  return std::nullopt;
}

}  // namespace hemm::test
