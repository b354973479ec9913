// What the live view of a device-only run draws (hemm-operator with a `vps`
// block, or with the SIMULATED bimanual device against its local planes), as
// plain primitives and text (no OpenGL here; device_live_view.cpp hands them
// to MuJoCo). The view's frame is the device frame H (D for the bimanual
// device):
//  - the SIMULATED bimanual device: the table and the column, both arms as
//    capsules between successive joint origins (forward kinematics of the
//    tick's joint angles, common/kinematics/arm7.h, on the rig's mounts and
//    link radii), each handle as a capsule along the flange's z axis; other
//    devices: each end-effector as a sphere;
//  - the VPS scene (frame W) placed in H once for the whole run: through the
//    end-effectors' mean T_W_H (translations averaged, the first one's axes).
//    With one mapping (the rigid scripted hands, the Omni) this is exact; the
//    bimanual device has one per arm (each hand's objects meet in W while the
//    hands stay 0.5 m apart), so the scene is drawn between the hands and a
//    line joins each end-effector to the object it holds;
//  - each object (mesh-frame pose of the tick): its bounding box in the mesh
//    frame, translucent, and a sparse subset of its pointshell points;
//  - the static scene: its voxmap's surface voxels merged into coarser cubes
//    until they fit a budget (the same drawing serves a live voxmap);
//  - the force (magenta) and torque (cyan) commanded to each end-effector
//    as arrows from it; the bimanual task's local planes (translucent);
//  - text: device, ticks, servo loop, VPS time, contacts and penetration per
//    pair, passivity observer energy, forces.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common/view/primitives.h"
#include "operator/bimanual/bimanual_config.h"
#include "operator/device/bimanual/simulation.h"
#include "operator/view/device_view_record.h"
#include "operator/view/view_feed.h"
#include "operator/view/voxmap_cubes.h"
#include "operator/vps/vps_model.h"
#include "operator/vps/vps_task.h"

namespace hemm::op {

namespace device_view_colours {
inline constexpr view::Rgba kArm{0.15f, 0.35f, 0.95f, 1.0f};
inline constexpr view::Rgba kHandle{0.95f, 0.85f, 0.10f, 1.0f};
inline constexpr view::Rgba kTable{0.45f, 0.35f, 0.28f, 1.0f};
inline constexpr view::Rgba kColumn{0.50f, 0.50f, 0.55f, 1.0f};
// Object 0 (right hand) green, object 1 (left hand) orange.
inline constexpr view::Rgba kObject[2] = {{0.10f, 0.85f, 0.20f, 1.0f}, {0.95f, 0.45f, 0.05f, 1.0f}};
inline constexpr float kObjectBoxAlpha = 0.6f;
inline constexpr view::Rgba kScene{0.62f, 0.62f, 0.68f, 1.0f};
inline constexpr view::Rgba kForce{0.95f, 0.10f, 0.65f, 1.0f};
inline constexpr view::Rgba kTorque{0.10f, 0.85f, 0.95f, 1.0f};
inline constexpr view::Rgba kGrasp{0.85f, 0.85f, 0.85f, 1.0f};
inline constexpr view::Rgba kPlane{0.55f, 0.55f, 0.95f, 0.30f};
}  // namespace device_view_colours

struct DeviceViewArms {
  device::bimanual::RigGeometry rig;
  std::array<device::bimanual::HandleSpec, device::bimanual::kArms> handles;
};

// A VPS object as drawn: its pointshell's bounding box and a sparse subset
// of its points, mesh frame M.
struct DeviceViewObject {
  Eigen::AlignedBox3d box_M;
  std::vector<Eigen::Vector3d> points_M;
};

struct DeviceViewPlane {
  Eigen::Vector3d point_H = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_H = Eigen::Vector3d::UnitZ();
};

// Everything about the run that does not change per tick (built once, off
// the servo thread).
struct DeviceSceneSetup {
  std::string device;  // shown in the text
  std::optional<DeviceViewArms> arms;
  std::array<Eigen::Isometry3d, device::kMaxEndEffectors> T_W_H{Eigen::Isometry3d::Identity(),
                                                                Eigen::Isometry3d::Identity()};
  Eigen::Isometry3d T_H_W = Eigen::Isometry3d::Identity();  // where W is drawn (see above)
  std::vector<DeviceViewObject> objects;
  VoxmapCubes scene;  // frame W
  std::array<std::optional<DeviceViewPlane>, device::kMaxEndEffectors> planes;
};

struct DeviceSceneBudget {
  std::size_t scene_cubes = 1500;  // static scene
  std::size_t object_points = 200;  // per object
};

// Every n-th point (n the smallest that keeps at most max_points) and the
// box of all points.
DeviceViewObject view_object(const vps::PointShell& shell, std::size_t max_points);
// W in H for the view: the mean of the end-effectors' T_W_H translations,
// the first one's axes, inverted.
Eigen::Isometry3d view_placement_of_W(const std::array<Eigen::Isometry3d, device::kMaxEndEffectors>& T_W_H,
                                      int end_effectors);

// A VPS run: the model, the task's mappings; `arms` (may be null): the
// SIMULATED bimanual device's configuration.
DeviceSceneSetup vps_view_setup(const VpsLocalModel& model, const VpsTaskParams& task, int end_effectors,
                                const device::bimanual::SimulationConfig* arms, std::string device_name,
                                const DeviceSceneBudget& budget = {});
// The bimanual device against its local planes.
DeviceSceneSetup bimanual_view_setup(const BimanualSetup& setup);

struct DeviceSceneStyle {
  double force_scale = 0.03;   // m of arrow per N
  double torque_scale = 1.0;   // m of arrow per N m
  double max_arrow = 0.3;      // m: longer arrows are cut to this (the text gives the magnitude)
  double arrow_width = 0.012;  // m
  double end_effector_radius = 0.02;  // devices without arms
  double point_radius = 0.003;        // pointshell points
};

// The style for a setup: as above with the arms; a quarter of every size
// and arrow scale without them (the view then frames the scene alone, a few
// centimetres across).
DeviceSceneStyle device_scene_style(const DeviceSceneSetup& setup);

// The primitives in H. tick may be null (no servo tick yet): then only what
// does not move (table, column, scene).
void build_device_scene(const DeviceSceneSetup& setup, const DeviceViewRecord* tick, const DeviceSceneStyle& style,
                        view::PrimitiveList& out);

// Where the picture looks from: the rig from the operator's side, above and
// to the right; without arms, the scene about W's origin.
view::CameraSpec default_device_camera(const DeviceSceneSetup& setup);

view::Overlay make_device_overlay(const DeviceSceneSetup& setup, const DeviceViewRecord* tick,
                                  const ServoHealth* servo);

}  // namespace hemm::op
