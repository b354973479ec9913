#include "tests/integration/latency/csv_columns.h"

#include <charconv>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace hemm::test {

const std::vector<double>& CsvColumns::operator[](const std::string& name) const {
  const auto it = col.find(name);
  if (it == col.end()) throw std::out_of_range("no column '" + name + "'");
  return it->second;
}

CsvColumns read_csv_columns(const std::string& path) {
  CsvColumns t;
  std::ifstream in(path);
  if (!in) {
    t.error = path + ": cannot open";
    return t;
  }
  std::string line;
  if (!std::getline(in, line) || line.empty()) {
    t.error = path + ": no header";
    return t;
  }
  std::vector<std::vector<double>*> cols;
  {
    std::stringstream ss(line);
    std::string name;
    while (std::getline(ss, name, ',')) cols.push_back(&t.col[name]);
  }
  std::vector<double> row(cols.size());
  while (std::getline(in, line)) {
    std::size_t k = 0;
    const char* p = line.data();
    const char* end = p + line.size();
    bool good = true;
    while (good && k < cols.size()) {
      const char* comma = p;
      while (comma < end && *comma != ',') ++comma;
      double v = 0.0;
      const auto r = std::from_chars(p, comma, v);
      good = r.ec == std::errc() && r.ptr == comma;
      if (good) row[k++] = v;
      p = comma < end ? comma + 1 : end;
      if (comma == end && k < cols.size()) good = false;
    }
    if (!good || k != cols.size()) {
      ++t.bad_rows;
      break;
    }
    for (std::size_t i = 0; i < cols.size(); ++i) cols[i]->push_back(row[i]);
    ++t.rows;
  }
  t.ok = true;
  return t;
}

}  // namespace hemm::test
