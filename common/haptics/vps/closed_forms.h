// Exact references of the VPS pressure model, F = K * integral(p n dA) over
// the penetrating surface of the pointshell object (p its depth in the other
// object, n its inward normal), for analytic shapes. The tests, the
// benchmarks and the engine report measure the engine against these.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

namespace hemm::vps {

// A sphere of radius R whose lowest point is delta past a plane (a
// half-space): p is the depth below the plane over the sphere's cap; the
// force is along the plane's outward normal.
//   F = 2 pi R^2 K (R (1 - u^3) / 3 + (delta - R)(1 - u^2) / 2), u = 1 - delta / R.
inline double sphere_halfspace_force(double K, double R, double delta) {
  if (delta <= 0) return 0.0;
  delta = std::min(delta, 2 * R);
  const double u0 = 1.0 - delta / R;
  return 2 * std::numbers::pi * R * R * K *
         (R * (1 - u0 * u0 * u0) / 3.0 + (delta - R) * (1 - u0 * u0) / 2.0);
}

// Volume of a sphere of radius R below a plane h above its lowest point
// (h clamped to [0, 2R]): pi h^2 (3R - h) / 3. sphere_halfspace_force is K
// times this volume (the pressure integral of a linear depth is the volume
// under the plane).
inline double sphere_cap_volume(double R, double h) {
  h = std::clamp(h, 0.0, 2 * R);
  return std::numbers::pi * h * h * (3 * R - h) / 3.0;
}

// Volume of a sphere (radius R, centre height zc) between the planes z = lo
// and z = hi (lo <= hi): its overlap with a plate of thickness hi - lo.
inline double sphere_slab_volume(double R, double zc, double lo, double hi) {
  return sphere_cap_volume(R, hi - (zc - R)) - sphere_cap_volume(R, lo - (zc - R));
}

// A plane (a flat face) at distance h from the centre of a sphere R: p is the
// sphere's depth R - |x - c| over the disc the sphere cuts from the plane;
// the force is along the face's inward normal.
inline double plane_sphere_force(double K, double R, double h) {
  if (h >= R) return 0.0;
  const double rho2 = R * R - h * h;
  return K * 2 * std::numbers::pi * (R * rho2 / 2 - (R * R * R - h * h * h) / 3);
}

// A sphere R1 (pointshell) against a sphere R2, centres D apart: p = R2 -
// |x - c2| over R1's cap inside R2, resolved along the centre line. The
// integrand is exact; the 1-D integral is taken by Simpson's rule with
// 2 * 10^4 panels (relative error far below 1e-8).
inline double sphere_sphere_force(double K, double R1, double R2, double D) {
  if (D >= R1 + R2) return 0.0;
  const double u0 = std::max(-1.0, (R1 * R1 + D * D - R2 * R2) / (2 * R1 * D));
  const int n = 20000;
  const double h = (1.0 - u0) / n;
  auto f = [&](double u) { return (R2 - std::sqrt(R1 * R1 + D * D - 2 * R1 * D * u)) * u; };
  double acc = f(u0) + f(1.0);
  for (int i = 1; i < n; ++i) acc += f(u0 + i * h) * (i % 2 ? 4 : 2);
  return 2 * std::numbers::pi * R1 * R1 * K * acc * h / 3.0;
}

}  // namespace hemm::vps
