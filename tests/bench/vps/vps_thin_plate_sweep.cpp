// Issue 23 item 6: a 20 mm sphere (1 mm pointshell) pushed at constant speed
// (0.05 mm a tick: 50 mm/s at 1 kHz) straight down through a 1 mm plate
// (voxmap at 1, 2 and 4 mm voxels, the default 3 distance layers, K 1e7
// N/m^3) and out below it, one pair state carried along. Per tick the force
// against the sphere centre's height, beside two exact references:
//   - the half-space behind the face it came through (K times the sphere's
//     volume below the plate's top face): what the model renders for shallow
//     contact, by design whatever the plate's thickness (no tunnelling);
//   - the volumetric overlap with the plate (K times the volume of sphere and
//     plate in common): zero once no part of the sphere overlaps the plate.
// Prints a table (every 2 mm of height) and, per voxel size, the force and
// contacts after separation and the error against the half-space while
// shallow (from 0.3 mm deep to 2 mm past the plate's lower face);
// writes every tick to CSV_FILE when given (deploy/plots/plot_vps_thin_plate.py).
//
// Usage: vps_thin_plate_sweep [CSV_FILE]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"

namespace {

using namespace hemm;

constexpr double kR = 0.02, kThickness = 0.001, kK = 1e7, kStep = 5e-5;
constexpr double kVoxels[] = {0.001, 0.002, 0.004};

Eigen::Isometry3d at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  return T;
}

struct Tick {
  double fz = 0, fxy = 0;
  int contacts = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc > 2 || (argc == 2 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help"))) {
    std::fprintf(stderr, "usage: %s [CSV_FILE]\n", argv[0]);
    return 2;
  }
  vps::PointShellParams pp;
  pp.voxel_size = 0.001;
  vps::PointShell ps;
  if (auto e = vps::build_pointshell(mesh::make_icosphere(kR, 5), pp, Eigen::Vector3d::Zero(), &ps)) {
    std::fprintf(stderr, "pointshell: %s\n", e->message.c_str());
    return 1;
  }
  // The plate: top face z = 0, bottom face z = -1 mm, 120 mm square.
  mesh::TriangleMesh plate;
  mesh::append_mesh(&plate, mesh::make_box({0.06, 0.06, kThickness / 2}, 4), at({0, 0, -kThickness / 2}));
  // Centre heights: from 2 mm above contact to 16 mm below separation (past
  // the deepest layers, 3 x 4 mm).
  const double z_start = kR + 0.002, z_end = -kThickness - kR - 0.016;
  const int n = static_cast<int>((z_start - z_end) / kStep) + 1;
  std::vector<std::vector<Tick>> runs;
  std::vector<int> layers;
  for (const double s : kVoxels) {
    vps::VoxmapParams vp;
    vp.voxel_size = s;
    vps::Voxmap vm;
    if (auto e = vps::build_voxmap(plate, vp, &vm, nullptr)) {
      std::fprintf(stderr, "voxmap: %s\n", e->message.c_str());
      return 1;
    }
    layers.push_back(vp.layers_out);
    vps::ContactParams cp;
    cp.stiffness = kK;
    vps::PairState state;
    vps::init_pair_state(ps, &state);
    std::vector<Tick> run(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      // Off the grid sideways, so no voxel boundary lines up with the sphere.
      const double zc = z_start - i * kStep;
      vps::PairResult r;
      vps::evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, at({0.00037, -0.00061, zc}),
                         cp, &state, &r);
      run[static_cast<std::size_t>(i)] = {r.on_shell.force.z(), r.on_shell.force.head<2>().norm(), r.contacts};
    }
    runs.push_back(std::move(run));
  }

  std::FILE* csv = nullptr;
  if (argc == 2) {
    csv = std::fopen(argv[1], "w");
    if (csv == nullptr) {
      std::fprintf(stderr, "cannot write %s\n", argv[1]);
      return 1;
    }
    std::fprintf(csv, "centre_z_mm,overlap,ref_halfspace_n,ref_plate_overlap_n");
    for (const double s : kVoxels) {
      const int mm = static_cast<int>(std::lround(s * 1e3));
      std::fprintf(csv, ",fz_%dmm_n,fxy_%dmm_n,contacts_%dmm", mm, mm, mm);
    }
    std::fprintf(csv, "\n");
  }
  std::printf("VPS thin plate: sphere R %.0f mm (1 mm pointshell, %zu points) pushed down through a %.1f mm plate at "
              "%.2f mm a tick, K %.0e N/m^3, default %d distance layers\n",
              kR * 1e3, ps.size(), kThickness * 1e3, kStep * 1e3, kK, layers[0]);
  std::printf("%9s | %8s | %10s %10s |", "centre z", "overlap", "half-space", "plate");
  for (const double s : kVoxels) std::printf("  F_z %.0f mm  contacts |", s * 1e3);
  std::printf("\n%9s | %8s | %10s %10s |", "mm", "", "N", "N");
  for (std::size_t k = 0; k < runs.size(); ++k) std::printf("  %9s %9s |", "N", "");
  std::printf("\n");
  struct Summary {
    double apart_force = 0, shallow_err = 0;
    int apart_contacts = 0, apart_ticks = 0;
  };
  std::vector<Summary> sum(runs.size());
  for (int i = 0; i < n; ++i) {
    const double zc = z_start - i * kStep;
    const double delta = -(zc - kR);  // the lowest point's depth below the top face
    const bool overlap = zc - kR < 0 && zc + kR > -kThickness;
    const double ref_hs = overlap ? vps::sphere_halfspace_force(kK, kR, delta) : 0.0;
    const double ref_plate = kK * vps::sphere_slab_volume(kR, zc, -kThickness, 0.0);
    if (csv != nullptr) {
      std::fprintf(csv, "%.5f,%d,%.6g,%.6g", zc * 1e3, overlap ? 1 : 0, ref_hs, ref_plate);
      for (const auto& run : runs) {
        const Tick& t = run[static_cast<std::size_t>(i)];
        std::fprintf(csv, ",%.6g,%.6g,%d", t.fz, t.fxy, t.contacts);
      }
      std::fprintf(csv, "\n");
    }
    for (std::size_t k = 0; k < runs.size(); ++k) {
      const Tick& t = runs[k][static_cast<std::size_t>(i)];
      if (!overlap && zc < 0) {
        ++sum[k].apart_ticks;
        sum[k].apart_force = std::max(sum[k].apart_force, std::hypot(t.fz, t.fxy));
        sum[k].apart_contacts = std::max(sum[k].apart_contacts, t.contacts);
      }
      if (delta >= 3e-4 && delta <= kThickness + 0.002)
        sum[k].shallow_err = std::max(sum[k].shallow_err, std::hypot(t.fz - ref_hs, t.fxy) / ref_hs);
    }
    if (i % 40 == 0) {
      std::printf("%9.2f | %8s | %10.3f %10.3f |", zc * 1e3, overlap ? "yes" : "no", ref_hs, ref_plate);
      for (const auto& run : runs) {
        const Tick& t = run[static_cast<std::size_t>(i)];
        std::printf("  %9.3f %9d |", t.fz, t.contacts);
      }
      std::printf("\n");
    }
  }
  std::printf("\nAfter separation (no part of the sphere overlaps the plate), and shallow (0.3 mm deep to 2 mm "
              "past the lower face) against the half-space:\n");
  for (std::size_t k = 0; k < runs.size(); ++k) {
    std::printf("  %.0f mm voxels (%d layers): %d ticks apart, max |F| %.4f N, max contacts %d; shallow |F| error "
                "max %.2f %%\n",
                kVoxels[k] * 1e3, layers[k], sum[k].apart_ticks, sum[k].apart_force, sum[k].apart_contacts,
                100 * sum[k].shallow_err);
  }
  if (csv != nullptr) {
    std::fclose(csv);
    std::printf("wrote %s\n", argv[1]);
  }
  return 0;
}
