// hemm-bimanual-workspace: the workspace of the SIMULATED bimanual interface
// as in the bimanual paper's Fig. 2. At each point of a grid over two
// sections of the rig (frame D of rig.h), the reachability index of each
// arm: the fraction of orientations, sampled near-uniformly over SO(3), at
// which the project's IK (common/kinematics/arm7_ik.h) reaches the flange
// pose within tolerance and joint limits. Points inside the table or the
// column are left out; collisions of the links with the table, the column
// or the other arm are not checked (the paper's index is kinematic too).
// Output: CSV (section, x, y, z, right, left); deploy/plots/plot_reachability.py
// draws the sections as PNG.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "common/kinematics/arm7_ik.h"
#include "operator/device/bimanual/rig.h"

namespace {

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

bool inside(const hb::Box& b, const Eigen::Vector3d& p) {
  return (p.array() >= b.min_D.array()).all() && (p.array() <= b.max_D.array()).all();
}

struct Section {
  const char* name;
  Eigen::Vector3d origin_D, u_D, v_D;  // points origin + i step u + j step v
  double u_len, v_len;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hemm-bimanual-workspace: reachability index (fraction of sampled flange orientations the IK "
               "reaches) of both arms of the SIMULATED bimanual interface over a horizontal and a vertical section "
               "of the rig, as CSV (the bimanual paper's Fig. 2; plot with deploy/plots/plot_reachability.py)."};
  std::string out;
  double step = 0.075, z_top = 0.40, x_front = -0.55;
  int orientations = 48;
  app.add_option("-o,--out", out, "CSV file to write: section,x,y,z,right,left (frame D, m; indices in [0, 1])")
      ->required();
  app.add_option("--step", step, "grid spacing [m], 0.02..0.5")->check(CLI::Range(0.02, 0.5));
  app.add_option("--orientations", orientations, "orientations sampled per point, 4..1000")
      ->check(CLI::Range(4, 1000));
  app.add_option("--z", z_top, "height of the horizontal section above the table [m], 0.02..1.2")
      ->check(CLI::Range(0.02, 1.2));
  app.add_option("--x", x_front, "x of the vertical (frontal) section [m], -1.2..-0.1 (the operator's side)")
      ->check(CLI::Range(-1.2, -0.1));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  std::ofstream f(out);
  if (!f) {
    std::fprintf(stderr, "hemm-bimanual-workspace: cannot write %s\n", out.c_str());
    return 1;
  }
  const hb::RigGeometry rig = hb::default_rig();
  const auto R = hk::sample_orientations(orientations);
  const auto seeds = hk::ik_seed_postures(rig.arm);
  const Section sections[] = {
      {"horizontal", Eigen::Vector3d(-1.2, -0.9, z_top), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 1.2, 1.8},
      {"vertical", Eigen::Vector3d(x_front, -0.9, 0.0), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(), 1.8, 1.3},
  };
  f << "section,x,y,z,right,left\n";
  const auto t0 = std::chrono::steady_clock::now();
  int points = 0;
  for (const Section& s : sections) {
    const int nu = static_cast<int>(std::floor(s.u_len / step + 1e-9)) + 1;
    const int nv = static_cast<int>(std::floor(s.v_len / step + 1e-9)) + 1;
    for (int i = 0; i < nu; ++i) {
      for (int j = 0; j < nv; ++j) {
        Eigen::Vector3d p = s.origin_D + i * step * s.u_D + j * step * s.v_D;
        p = (p.array().abs() < 1e-9).select(0.0, p);  // no "-0.0000" in the file
        if (p.z() <= rig.table.max_D.z() || inside(rig.column, p)) continue;
        double idx[hb::kArms];
        for (int a = 0; a < hb::kArms; ++a) {
          const Eigen::Vector3d p_A = rig.T_D_A[static_cast<std::size_t>(a)].inverse() * p;
          idx[a] = hk::reachability(rig.arm, p_A, R, seeds).index();
        }
        char line[160];
        std::snprintf(line, sizeof line, "%s,%.4f,%.4f,%.4f,%.4f,%.4f\n", s.name, p.x(), p.y(), p.z(), idx[0], idx[1]);
        f << line;
        ++points;
      }
    }
  }
  f.close();
  if (!f) {
    std::fprintf(stderr, "hemm-bimanual-workspace: write error on %s\n", out.c_str());
    return 1;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%d points x 2 arms x %d orientations in %.1f s -> %s\n", points, orientations, s, out.c_str());
  return 0;
}
