// A renderer's time-critical work budget over a run (common/haptics/vps/
// work_budget.h) for the station summaries: one line of text and
// proto/report.proto's WorkBudget.
#pragma once

#include <string>

#include "common/haptics/vps/work_budget.h"

namespace hemm::report {
class WorkBudget;  // report.pb.h
}

namespace hemm::op {

struct WorkBudgetSummary {
  vps::TimeBudgetParams params;
  vps::WorkRateCalibration calibration;
  vps::WorkBudgetStats stats;
};

std::string to_string(const WorkBudgetSummary& s);
void to_report(const WorkBudgetSummary& s, report::WorkBudget* out);

}  // namespace hemm::op
