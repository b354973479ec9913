// Where tests write their outputs: a fresh directory per call, so two ctest
// runs of one build tree at once (or two tests of one run in parallel) never
// write the same file. Header-only: any test can use it without a library.
#pragma once

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

namespace hemm::test {

// A new directory under $TMPDIR (else /tmp) named `prefix`-XXXXXX (mkdtemp).
// Throws if none can be made: a test that cannot have its own directory
// fails rather than share one. The directory is left for inspection.
inline std::string make_temp_dir(const std::string& prefix = "hemm-test") {
  const char* base = std::getenv("TMPDIR");
  std::string tmpl = std::string(base != nullptr && *base != '\0' ? base : "/tmp") + "/" + prefix + "-XXXXXX";
  if (::mkdtemp(tmpl.data()) == nullptr) {
    throw std::runtime_error("cannot make a temporary directory " + tmpl + ": " + std::strerror(errno));
  }
  return tmpl;
}

}  // namespace hemm::test
