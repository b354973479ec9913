#include "operator/telemanip/hand_trace.h"

#include <iomanip>
#include <sstream>

namespace hemm::op::telemanip {

std::string hand_trace_csv(const std::vector<HandTraceSample>& rows) {
  std::ostringstream os;
  os << "t_s,clock_s,remote_clock_s,mode,squeeze_N";
  for (const char* arm : {"right", "left"}) {
    for (const char* flag : {"pressed", "clutched", "holding"}) os << ',' << arm << '_' << flag;
    for (const char* what : {"cmd", "remote", "felt", "held", "remote_force"})
      for (const char* axis : {"x", "y", "z"}) os << ',' << arm << '_' << what << '_' << axis;
    os << ',' << arm << "_cmd_opening_m," << arm << "_remote_opening_m";
  }
  os << '\n';
  const std::int64_t t0 = rows.empty() ? 0 : rows.front().t_ns;
  for (const HandTraceSample& r : rows) {
    // Clocks to the microsecond whatever the uptime; the rest at 6 digits.
    os << std::fixed << std::setprecision(6) << 1e-9 * static_cast<double>(r.t_ns - t0) << ','
       << 1e-9 * static_cast<double>(r.t_ns) << ',' << 1e-9 * static_cast<double>(r.remote_ns) << std::defaultfloat
       << std::setprecision(6) << ',' << (r.direct ? "direct" : "model") << ',' << r.squeeze_n;
    for (const HandTraceArm& a : r.arm) {
      os << ',' << a.pressed << ',' << a.clutched << ',' << a.holding;
      for (const Eigen::Vector3d* v : {&a.commanded_A, &a.remote_A, &a.felt_A, &a.held_A, &a.remote_force_A})
        os << ',' << v->x() << ',' << v->y() << ',' << v->z();
      os << ',' << a.commanded_opening_m << ',' << a.remote_opening_m;
    }
    os << '\n';
  }
  return os.str();
}

}  // namespace hemm::op::telemanip
