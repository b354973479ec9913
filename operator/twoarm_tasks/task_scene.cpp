#include "operator/twoarm_tasks/task_scene.h"

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace hemm::twoarm_tasks {

namespace {

struct SceneKey {
  const char* name;
  int count;
};
struct SceneObject {
  const char* name;
  std::vector<SceneKey> keys;
};

const std::vector<SceneObject>& scene_objects() {
  static const std::vector<SceneObject> objects = {
      {"box", {{"centre", 3}, {"size", 3}}},
      {"shelf", {{"place", 3}}},
      {"peg", {{"centre", 3}, {"half", 1}, {"length", 1}}},
      {"hole", {{"top", 3}, {"depth", 1}}},
      {"bar", {{"centre", 3}, {"radius", 1}, {"length", 1}}},
  };
  return objects;
}

std::optional<double> scene_number(const std::string& word) {
  double v = 0.0;
  const char* end = word.data() + word.size();
  const auto r = std::from_chars(word.data(), end, v);
  if (r.ec != std::errc{} || r.ptr != end || !std::isfinite(v)) return std::nullopt;
  return v;
}

using SceneValues = std::map<std::string, std::vector<double>>;

}  // namespace

TaskSceneResult parse_task_scene(const std::string& text, const std::string& file) {
  TaskSceneResult out;
  std::map<std::string, SceneValues> seen;
  std::istringstream lines(text);
  std::string line;
  int line_no = 0;
  auto fail = [&](const std::string& why) {
    out.error = file + ":" + std::to_string(line_no) + ": " + why;
    return out;
  };
  while (std::getline(lines, line)) {
    ++line_no;
    std::istringstream words(line);
    std::string first;
    if (!(words >> first) || first != "task:") continue;
    std::string object;
    if (!(words >> object)) return fail("a task line names no object");
    const SceneObject* spec = nullptr;
    for (const SceneObject& o : scene_objects()) {
      if (object == o.name) spec = &o;
    }
    if (spec == nullptr) return fail("unknown task object '" + object + "' (box, shelf, peg, hole, bar)");
    if (seen.count(object) != 0) return fail("a second line for '" + object + "'");
    SceneValues values;
    std::string key;
    while (words >> key) {
      const SceneKey* k = nullptr;
      for (const SceneKey& c : spec->keys) {
        if (key == c.name) k = &c;
      }
      if (k == nullptr) return fail("'" + object + "' has no key '" + key + "'");
      if (values.count(key) != 0) return fail("'" + object + "': '" + key + "' given twice");
      std::vector<double>& v = values[key];
      for (int i = 0; i < k->count; ++i) {
        std::string w;
        if (!(words >> w)) return fail("'" + object + " " + key + "' needs " + std::to_string(k->count) + " numbers");
        const auto x = scene_number(w);
        if (!x) return fail("'" + object + " " + key + "': '" + w + "' is not a finite number");
        v.push_back(*x);
      }
    }
    for (const SceneKey& c : spec->keys) {
      if (values.count(c.name) == 0) return fail("'" + object + "' lacks '" + c.name + "'");
    }
    for (const auto& [k, v] : values) {
      if ((k == "size" || k == "half" || k == "radius" || k == "length" || k == "depth") && !(v[0] > 0.0 && (v.size() < 3 || (v[1] > 0.0 && v[2] > 0.0))))
        return fail("'" + object + " " + k + "' must be positive");
    }
    seen[object] = std::move(values);
  }
  for (const SceneObject& o : scene_objects()) {
    if (seen.count(o.name) == 0) {
      out.error = file + ": no 'task: " + std::string(o.name) + "' line";
      return out;
    }
  }
  auto v3 = [&](const char* o, const char* k) {
    const std::vector<double>& v = seen[o][k];
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  auto v1 = [&](const char* o, const char* k) { return seen[o][k][0]; };
  TaskScene s;
  s.box_centre = v3("box", "centre");
  s.box_size = v3("box", "size");
  s.shelf_place = v3("shelf", "place");
  s.peg_centre = v3("peg", "centre");
  s.peg_half_width_m = v1("peg", "half");
  s.peg_length_m = v1("peg", "length");
  s.hole_top = v3("hole", "top");
  s.hole_depth_m = v1("hole", "depth");
  s.bar_centre = v3("bar", "centre");
  s.bar_radius_m = v1("bar", "radius");
  s.bar_length_m = v1("bar", "length");
  out.scene = s;
  return out;
}

TaskSceneResult load_task_scene(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    TaskSceneResult r;
    r.error = path + ": cannot be read";
    return r;
  }
  std::ostringstream text;
  text << in.rdbuf();
  return parse_task_scene(text.str(), path);
}

}  // namespace hemm::twoarm_tasks
