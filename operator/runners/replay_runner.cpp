// --replay of a session recording (no link; the model and the servo task
// rebuilt from the file, operator/record/session_replay.h, optionally seen in
// the live view) and --export-mcap of one (operator/record/session_mcap.h).
#include <iostream>
#include <memory>
#include <optional>

#include "operator/record/session_mcap.h"
#include "operator/record/session_recording.h"
#include "operator/record/session_replay.h"
#include "operator/runners/runners.h"
#ifdef HEMM_WITH_VIEW
#include "operator/view/live_view.h"
#endif

namespace hemm::op::runner {

namespace {

// Loads a recording (or its MCAP export) for --replay or --export-mcap:
// false if nothing of it is readable (said on stderr); a broken file's
// readable part is used, *broke set and said.
bool load_session(const std::string& path, const char* using_it, Recording* rec, bool* broke) {
  const std::optional<std::string> e = load_recording(path, rec);
  *broke = e.has_value();
  if (e && rec->records == 0) {
    std::cerr << "hemm-operator: " << *e << "\n";
    return false;
  }
  if (e) std::cerr << "hemm-operator: " << *e << "; " << using_it << " the readable part\n";
  return true;
}

}  // namespace

int replay_recording(const OperatorArgs& a) {
  Recording rec;
  bool broke = false;
  if (!load_session(a.replay_file, "replaying", &rec, &broke)) return net::kExitUsage;
  if (!rec.header.telemanip_mode().empty()) {
#ifdef HEMM_OPERATOR_HAVE_TELEMANIP
    if (a.view_opts.enabled()) std::cerr << "hemm-operator: --replay --view: a telemanip session has no live view yet\n";
    const int rc = replay_telemanip_recording(rec, a);
    return broke && rc == net::kExitOk ? net::kExitUsage : rc;
#else
    std::cerr << "hemm-operator: --replay: a telemanip session; this build has no telemanipulation\n";
    return net::kExitUsage;
#endif
  }
  SessionReplayOptions ro;
  ro.speed = a.replay_speed;
#ifdef HEMM_WITH_VIEW
  std::unique_ptr<OperatorLiveView> live_view;
  if (a.view_opts.enabled()) {
    live_view = std::make_unique<OperatorLiveView>(a.view_opts, LiveViewLinks{});
    ViewFeed& feed = live_view->feed();
    ro.on_snapshot = [&feed](const OperatorModelSnapshot& s) { feed.on_snapshot(s); };
    ro.ticks = &feed.ticks();
    live_view->start();
  }
#endif
  const SessionReplayResult r = replay_session(rec, ro);
  if (!r.warning.empty()) std::cerr << "hemm-operator: --replay: " << r.warning << "\n";
#ifdef HEMM_WITH_VIEW
  if (live_view) live_view->stop();
#endif
  std::cout << "replay: ticks=" << r.ticks << " model_steps=" << r.steps << " ticks_missing=" << r.ticks_missing
            << " force_mismatches=" << r.force_mismatches << " max_force_error_N=" << r.max_force_error_N
            << " mode_mismatches=" << r.mode_mismatches << " recorded_s=" << r.recorded_s << " wall_s=" << r.wall_s
            << (r.stopped.empty() ? "" : " stopped=\"" + r.stopped + "\"") << "\n";
  std::string error;
  if (!a.replay_json.empty() && !net::write_text_file(a.replay_json, to_json(r), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    return net::kExitInternal;
  }
  return broke ? net::kExitUsage : net::kExitOk;
}

int export_recording_as_mcap(const std::string& in, const std::string& out) {
  Recording rec;
  bool broke = false;
  if (!load_session(in, "exporting", &rec, &broke)) return net::kExitUsage;
  try {
    std::cout << to_string(export_mcap(rec, out)) << std::flush;
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: --export-mcap: " << e.what() << "\n";
    return net::kExitUsage;
  }
  return broke ? net::kExitUsage : net::kExitOk;
}

}  // namespace hemm::op::runner
