// Test helpers for the operator station's world log (operator_task.h
// StationLogRecord, the .world.csv the station writes): rows by column name.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace hemm::test {

inline std::vector<std::map<std::string, double>> read_world_log(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> names;
  std::vector<std::map<std::string, double>> rows;
  if (!std::getline(in, line)) return rows;
  {
    std::stringstream ss(line);
    std::string n;
    while (std::getline(ss, n, ',')) names.push_back(n);
  }
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string v;
    std::map<std::string, double> r;
    for (std::size_t i = 0; i < names.size() && std::getline(ss, v, ','); ++i) r[names[i]] = std::strtod(v.c_str(), nullptr);
    rows.push_back(std::move(r));
  }
  return rows;
}

inline double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace hemm::test
