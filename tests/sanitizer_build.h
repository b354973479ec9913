// Whether this test binary is the sanitizer build's (deploy/run.sh test's
// second pass, ASan + UBSan). A parameter sweep whose cases all run the same
// code takes one representative case there: the release pass asserts the
// whole sweep; the sanitizer pass looks for memory and undefined-behaviour
// errors in that code, which the other cases would only repeat at ten times
// the cost (CI time; docs/testing.md).
#pragma once

namespace hemm::test {

#ifdef HEMM_SANITIZE
inline constexpr bool kSanitizerBuild = true;
#else
inline constexpr bool kSanitizerBuild = false;
#endif

}  // namespace hemm::test
