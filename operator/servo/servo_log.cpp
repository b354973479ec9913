#include "operator/servo/servo_log.h"

#include <charconv>

namespace hemm::servo {

const char* servo_log_header() {
  return "t_ns,tick,wake_latency_ns,compute_ns,"
         "dev_x,dev_y,dev_z,dev_vx,dev_vy,dev_vz,"
         "proxy_x,proxy_y,proxy_z,ip_x,ip_y,ip_z,fx,fy,fz,"
         "buttons,mode,model_age_ns,model_version,link_rtt_ns,link_offset_ns";
}

namespace {
class Writer {
 public:
  Writer(char* b, std::size_t n) : p_(b), end_(b + n) {}
  template <class V>
  void put(V v) {
    if (p_ == nullptr) return;
    const auto r = std::to_chars(p_, end_, v);
    if (r.ec != std::errc() || r.ptr == end_) {
      p_ = nullptr;
      return;
    }
    p_ = r.ptr;
    *p_++ = ',';
  }
  void put3(const double* v) {
    for (int i = 0; i < 3; ++i) put(v[i]);
  }
  std::size_t finish(const char* begin) {
    if (p_ == nullptr) return 0;
    p_[-1] = '\n';  // the last separator becomes the line end
    return static_cast<std::size_t>(p_ - begin);
  }

 private:
  char* p_;
  char* end_;
};
}  // namespace

std::size_t format_servo_log_record(const ServoLogRecord& r, char* buf, std::size_t size) {
  Writer w(buf, size);
  w.put(r.t_ns);
  w.put(r.tick);
  w.put(r.wake_latency_ns);
  w.put(r.compute_ns);
  w.put3(r.device_position);
  w.put3(r.device_velocity);
  w.put3(r.proxy_position);
  w.put3(r.interaction_point);
  w.put3(r.force);
  w.put(r.buttons);
  w.put(r.mode);
  w.put(r.model_age_ns);
  w.put(r.model_version);
  w.put(r.link_rtt_ns);
  w.put(r.link_offset_ns);
  return w.finish(buf);
}

}  // namespace hemm::servo
