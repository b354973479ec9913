#include "robot_side/truth/scene_slice.h"

#include <mujoco/mujoco.h>

#include "common/mesh/primitives.h"
#include "common/sim/mujoco_owner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace hemm::robot {
namespace {

// A shape axis counts as vertical when it leans less than this (rad, small
// angle): over a 2.5 m wall that is 2.5 um, far below any sensor's noise.
constexpr double kVerticalTolerance = 1e-6;

std::string geom_name(const mjModel* m, int g) {
  const char* n = mj_id2name(m, mjOBJ_GEOM, g);
  if (n != nullptr && n[0] != '\0') return n;
  return "geom#" + std::to_string(g);
}

const char* type_name(int type) {
  switch (type) {
    case mjGEOM_PLANE: return "plane";
    case mjGEOM_HFIELD: return "hfield";
    case mjGEOM_SPHERE: return "sphere";
    case mjGEOM_CAPSULE: return "capsule";
    case mjGEOM_ELLIPSOID: return "ellipsoid";
    case mjGEOM_CYLINDER: return "cylinder";
    case mjGEOM_BOX: return "box";
    case mjGEOM_MESH: return "mesh";
    default: return "other";
  }
}

// Column j of the row-major geom_xmat is the geom's local axis j in W.
Eigen::Vector3d axis(const mjtNum* xmat, int j) { return {xmat[j], xmat[3 + j], xmat[6 + j]}; }
double horizontal(const Eigen::Vector3d& a) { return std::hypot(a.x(), a.y()); }

template <class... A>
std::string fmt(const char* f, A... a) {
  char buf[160];
  std::snprintf(buf, sizeof buf, f, a...);
  return buf;
}

}  // namespace

SceneSlice slice_scene(const mjModel_* m, const mjData_* d, double z) {
  SceneSlice out;
  out.height = z;
  for (int g = 0; g < m->ngeom; ++g) {
    const int body = m->geom_bodyid[g];
    if (m->body_weldid[body] != 0 || m->body_mocapid[body] >= 0) {
      ++out.moving_geoms;
      continue;
    }
    const int type = m->geom_type[g];
    const mjtNum* size = m->geom_size + 3 * g;
    const mjtNum* xmat = d->geom_xmat + 9 * g;
    const Eigen::Vector3d c(d->geom_xpos[3 * g], d->geom_xpos[3 * g + 1], d->geom_xpos[3 * g + 2]);
    const Eigen::Vector2d c2 = c.head<2>();
    const double dz = z - c.z();
    SliceEntry e{geom_name(m, g), type_name(type), ""};

    switch (type) {
      case mjGEOM_PLANE: {
        // A plane's normal is its local z. Horizontal: a floor or ceiling, not
        // an obstacle in the slice. Any other plane is an infinite wall.
        if (horizontal(axis(xmat, 2)) < kVerticalTolerance) {
          e.detail = "horizontal plane (floor/ceiling)";
          out.off_slice.push_back(std::move(e));
        } else {
          e.detail = "non-horizontal plane (unbounded) not represented";
          out.skipped.push_back(std::move(e));
        }
        break;
      }
      case mjGEOM_SPHERE: {
        const double r = size[0];
        if (std::abs(dz) >= r) {
          e.detail = fmt("z in [%.3f, %.3f]", c.z() - r, c.z() + r);
          out.off_slice.push_back(std::move(e));
          break;
        }
        const double rs = std::sqrt(r * r - dz * dz);
        out.scene.circles.push_back({c2, rs});
        e.detail = fmt("circle centre (%.4f, %.4f) r %.4f", c2.x(), c2.y(), rs);
        out.included.push_back(std::move(e));
        break;
      }
      case mjGEOM_BOX: {
        // Exact z half-extent of the (possibly tilted) box.
        double hz = 0.0;
        int up = -1;
        for (int j = 0; j < 3; ++j) {
          const Eigen::Vector3d a = axis(xmat, j);
          hz += std::abs(a.z()) * size[j];
          if (horizontal(a) < kVerticalTolerance) up = j;
        }
        if (std::abs(dz) > hz) {
          e.detail = fmt("z in [%.3f, %.3f]", c.z() - hz, c.z() + hz);
          out.off_slice.push_back(std::move(e));
          break;
        }
        if (up < 0) {
          e.detail = "tilted box (no vertical axis) reaches the slice";
          out.skipped.push_back(std::move(e));
          break;
        }
        const int i = (up + 1) % 3, k = (up + 2) % 3;
        const Eigen::Vector2d a = axis(xmat, i).head<2>().normalized() * size[i];
        const Eigen::Vector2d b = axis(xmat, k).head<2>().normalized() * size[k];
        haptics::add_polygon(out.scene, {c2 + a + b, c2 - a + b, c2 - a - b, c2 + a - b});
        e.detail = fmt("rectangle centre (%.4f, %.4f) yaw %.4f rad", c2.x(), c2.y(), std::atan2(a.y(), a.x()));
        out.included.push_back(std::move(e));
        break;
      }
      case mjGEOM_CYLINDER:
      case mjGEOM_CAPSULE: {
        // size: radius, half-length of the axis (local z); a capsule adds caps.
        const Eigen::Vector3d a = axis(xmat, 2);
        const double r = size[0], h = size[1];
        const double lean = horizontal(a);
        const double hz = std::abs(a.z()) * h + (type == mjGEOM_CAPSULE ? r : r * lean);
        if (std::abs(dz) > hz) {
          e.detail = fmt("z in [%.3f, %.3f]", c.z() - hz, c.z() + hz);
          out.off_slice.push_back(std::move(e));
          break;
        }
        if (lean >= kVerticalTolerance) {
          e.detail = fmt("axis tilted %.4f rad from vertical, reaches the slice", std::asin(std::min(1.0, lean)));
          out.skipped.push_back(std::move(e));
          break;
        }
        double rs = r;
        if (type == mjGEOM_CAPSULE && std::abs(dz) > h) {
          const double cap = std::abs(dz) - h;  // height into the hemispherical cap
          rs = std::sqrt(std::max(0.0, r * r - cap * cap));
        }
        if (!(rs > 0.0)) {
          e.detail = "touches the slice in a point";
          out.off_slice.push_back(std::move(e));
          break;
        }
        out.scene.circles.push_back({c2, rs});
        e.detail = fmt("circle centre (%.4f, %.4f) r %.4f", c2.x(), c2.y(), rs);
        out.included.push_back(std::move(e));
        break;
      }
      default: {
        // Ellipsoid, mesh, height field: only the bounding sphere is cheap and
        // exact as a bound; if it reaches the slice, say so.
        const double rb = m->geom_rbound[g];
        if (rb > 0.0 && std::abs(dz) > rb) {
          e.detail = fmt("bounding sphere z in [%.3f, %.3f]", c.z() - rb, c.z() + rb);
          out.off_slice.push_back(std::move(e));
        } else {
          e.detail = std::string(type_name(type)) + " not represented (only boxes, cylinders, capsules, spheres)";
          out.skipped.push_back(std::move(e));
        }
        break;
      }
    }
  }
  return out;
}

namespace {

// Loads the MJCF file, runs mj_forward at qpos0 and hands the model to f.
template <class F>
bool with_scene(const std::string& path, std::string* error, F&& f) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    if (error) *error = path + ": no such scene file";
    return false;
  }
  sim::MujocoOwner scene;
  try {
    scene = sim::MujocoOwner::from_file(path);
  } catch (const std::runtime_error& e) {
    if (error) *error = std::string("MuJoCo could not load the scene: ") + e.what();  // "PATH: MuJoCo's message"
    return false;
  }
  mj_forward(scene.m(), scene.d());
  f(scene.m(), scene.d());
  return true;
}

}  // namespace

bool load_scene_slice(const std::string& path, double z, SceneSlice* out, std::string* error) {
  if (!std::isfinite(z)) {
    if (error) *error = path + ": slice height must be finite";
    return false;
  }
  return with_scene(path, error, [&](const mjModel* m, const mjData* d) { *out = slice_scene(m, d, z); });
}

bool load_scene_meshes(const std::string& path, const Eigen::AlignedBox3d& region_W, SceneMeshes* out,
                       std::string* error) {
  return with_scene(path, error, [&](const mjModel* m, const mjData* d) {
    SceneMeshes r;
    for (int g = 0; g < m->ngeom; ++g) {
      const int body = m->geom_bodyid[g];
      if (m->body_weldid[body] != 0 || m->body_mocapid[body] >= 0) continue;  // the robot
      SliceEntry e{geom_name(m, g), type_name(m->geom_type[g]), ""};
      const mjtNum* xmat = d->geom_xmat + 9 * g;
      const Eigen::Vector3d c(d->geom_xpos[3 * g], d->geom_xpos[3 * g + 1], d->geom_xpos[3 * g + 2]);
      const double rb = m->geom_rbound[g];  // bounding sphere (0 for planes: infinite)
      if (m->geom_type[g] == mjGEOM_PLANE || rb <= 0.0) {
        e.detail = "plane";
        r.off_region.push_back(e);
        continue;
      }
      const mjtNum* size = m->geom_size + 3 * g;
      // A box's own bounds (|R| size); a bounding sphere for the rest.
      Eigen::Vector3d half = Eigen::Vector3d::Constant(rb);
      if (m->geom_type[g] == mjGEOM_BOX) {
        half.setZero();
        for (int j = 0; j < 3; ++j) half += axis(xmat, j).cwiseAbs() * size[j];
      }
      const Eigen::AlignedBox3d bound(c - half, c + half);
      if (!bound.intersects(region_W)) {
        e.detail = "outside the region";
        r.off_region.push_back(e);
        continue;
      }
      SceneMeshPart part;
      part.name = e.name;
      switch (m->geom_type[g]) {
        case mjGEOM_BOX: part.mesh = mesh::make_box(Eigen::Vector3d(size[0], size[1], size[2]), 1); break;
        // 128 sides / an icosphere of 5 subdivisions: within 0.03 % of the
        // radius (12 um at 4 cm), far below any voxmap's voxel.
        case mjGEOM_CYLINDER: part.mesh = mesh::make_cylinder(size[0], size[1], 128); break;
        case mjGEOM_SPHERE: part.mesh = mesh::make_icosphere(size[0], 5); break;
        default:
          e.detail = "only boxes, cylinders and spheres are meshed";
          r.skipped.push_back(e);
          continue;
      }
      for (Eigen::Vector3d& v : part.mesh.vertices)
        v = c + axis(xmat, 0) * v.x() + axis(xmat, 1) * v.y() + axis(xmat, 2) * v.z();
      r.parts.push_back(std::move(part));
    }
    *out = std::move(r);
  });
}

}  // namespace hemm::robot
