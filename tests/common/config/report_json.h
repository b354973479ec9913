// Tests of the JSON reports (proto/report.proto printed by config::to_json):
// reads a printed report back into its message the strict way (an unknown
// key, a malformed value or a missing comma fails the test).
#pragma once

#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <string>

namespace hemm::test {

template <class Report>
Report read_report_json(const std::string& json) {
  Report r;
  google::protobuf::util::JsonParseOptions o;
  o.ignore_unknown_fields = false;
  const auto st = google::protobuf::util::JsonStringToMessage(json, &r, o);
  EXPECT_TRUE(st.ok()) << Report::descriptor()->name() << ": " << st.ToString() << "\n" << json;
  return r;
}

}  // namespace hemm::test
