// Whether this test binary is the sanitizer build's (deploy/run.sh test's
// second pass, ASan + UBSan). A parameter sweep whose cases all run the same
// code takes one representative case there: the release pass asserts the
// whole sweep; the sanitizer pass looks for memory and undefined-behaviour
// errors in that code, which the other cases would only repeat at ten times
// the cost (CI time; docs/testing.md).
#pragma once

#include <cstddef>
#include <initializer_list>
#include <vector>

namespace hemm::test {

#ifdef HEMM_SANITIZE
inline constexpr bool kSanitizerBuild = true;
#else
inline constexpr bool kSanitizerBuild = false;
#endif

// A sweep's cases: all of them in the release pass, in the sanitizer pass
// only those at `keep` (indices into `all`), the representative ones.
template <class T>
std::vector<T> sanitizer_cases(const std::vector<T>& all, std::initializer_list<std::size_t> keep) {
  if (!kSanitizerBuild) return all;
  std::vector<T> some;
  for (const std::size_t i : keep) some.push_back(all.at(i));
  return some;
}

}  // namespace hemm::test
