// One CSV line's comma-separated fields (the traces and logs hemm writes
// quote nothing). Header-only: any test or benchmark can use it.
#pragma once

#include <sstream>
#include <string>
#include <vector>

namespace hemm::test {

inline std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  for (std::string f; std::getline(in, f, ',');) out.push_back(f);
  return out;
}

}  // namespace hemm::test
