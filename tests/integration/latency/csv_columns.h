// Test helper: a numeric CSV with one header line, read into named columns
// (the operator's servo and world logs). A row with the wrong field count (a
// log cut mid-line when a process was stopped) ends the table; it is counted.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace hemm::test {

struct CsvColumns {
  std::map<std::string, std::vector<double>> col;
  std::size_t rows = 0;
  std::size_t bad_rows = 0;  // rows cut short or with a non-number
  bool ok = false;           // file read and header present
  std::string error;

  const std::vector<double>& operator[](const std::string& name) const;
  bool has(const std::string& name) const { return col.count(name) != 0; }
};

CsvColumns read_csv_columns(const std::string& path);

}  // namespace hemm::test
