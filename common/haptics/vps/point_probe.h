// The 3-DoF point probe for a 3-DoF device (the Omni) against a signed
// voxmap (the live voxmap built from depth clouds, frame W): a 3D god-object
// (Zilles & Salisbury) on the voxmap's signed distance field, the 3D
// counterpart of HEMM's virtual proxy (common/haptics/proxy).
//
// The probe is a sphere of radius rho (ProxyModel::probe_radius): its centre
// may go where the field phi (sdf_hermite) is at least rho. Every tick the
// proxy moves from where it was toward the device point, swept: the segment
// is sampled every march_step (a quarter voxel) and the first crossing of
// phi = rho is refined by bisection, so the proxy never tunnels through a
// surface layer; in contact the motion is projected onto the tangent plane
// (normal: the field's gradient) and slides, then is retracted onto the
// surface; a slide that runs into the surface it slides on (a bumpy field
// built from noisy clouds) steps back out along the normal there when that
// takes less than half a voxel, and stops otherwise (a wall ahead). Up to max_iterations such steps, at most max_step of motion per
// tick. A surface that appears through the proxy (a new snapshot) pushes it
// out along the gradient (counted in depenetrations), the one motion not
// swept.
//
// Force: the proxy's force law (detail::proxy_force: spring + damping along
// (proxy - device) / scale, unilateral, clamped to the device's peak and
// continuous ratings), now in 3D. With no voxmap the proxy follows the device
// point and the force is zero.
//
// Bounded tick: field evaluations per tick (PointProbeData::work) are at
// most point_probe_max_work (a gradient counts 6); no allocation, no locks.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "common/haptics/proxy/virtual_proxy.h"

namespace hemm::vps {

struct Voxmap;

struct PointProbeParams {
  haptics::ProxyModel force;  // probe_radius (m in W), stiffness, damping, limits, period
  double max_step = 0.02;     // m in W per tick (20 m/s: far beyond a hand at any 3D exploration scale)
  int max_iterations = 4;     // move/slide steps per tick
  double march_step_voxels = 0.25;  // sweep sampling, in voxels of the map
};

// Empty when usable.
std::string validate(const PointProbeParams& p);

struct PointProbeData {
  bool initialized = false;
  Eigen::Vector3d proxy_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d device_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();  // N on the device, W axes
  Eigen::Vector3d spring_prev = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_W = Eigen::Vector3d::UnitZ();  // of the contact (valid while contact)
  double force_filtered = 0.0, force_limit = 0.0;
  bool clamped = false;
  bool contact = false;
  double phi = 0.0;  // field at the proxy after the tick
  std::uint64_t ticks = 0, depenetrations = 0, rejected_inputs = 0;
  std::uint64_t work = 0, max_work = 0;  // field evaluations (gradient: 6)
};

void point_probe_reset(PointProbeData& d, const Eigen::Vector3d& at_W);

// One servo tick toward device_W (the interaction point in W) against vm
// (frame W; may be null: no model yet). scale: W metres per device metre.
// A non-finite input keeps the proxy and outputs zero force.
void point_probe_tick(const PointProbeParams& p, const Voxmap* vm, PointProbeData& d, const Eigen::Vector3d& device_W,
                      double scale) noexcept;

// The bound on PointProbeData::work for a map of this voxel size.
std::uint64_t point_probe_max_work(const PointProbeParams& p, double voxel_size);

}  // namespace hemm::vps
