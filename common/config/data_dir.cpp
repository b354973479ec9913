#include "common/config/data_dir.h"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace hemm::config {

std::vector<std::string> data_dir_candidates(const DataDirInputs& in) {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  if (!in.env.empty()) out.push_back(in.env);
  if (!in.executable.empty()) {
    const fs::path bin = fs::path(in.executable).parent_path();
    out.push_back((bin.parent_path() / "share" / "hemm").lexically_normal().string());
    std::error_code ec;
    if (!in.build_bin_dir.empty() && !in.source_data_dir.empty() && fs::equivalent(bin, in.build_bin_dir, ec))
      out.push_back(in.source_data_dir);
  }
  if (!in.install_data_dir.empty()) out.push_back(in.install_data_dir);
  return out;
}

DataDirInputs this_process_data_dir_inputs() {
  DataDirInputs in;
  if (const char* e = std::getenv("HEMM_DATA_DIR")) in.env = e;
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) in.executable = exe.string();
#ifdef HEMM_BUILD_BIN_DIR
  in.build_bin_dir = HEMM_BUILD_BIN_DIR;
#endif
#ifdef HEMM_SOURCE_DATA_DIR
  in.source_data_dir = HEMM_SOURCE_DATA_DIR;
#endif
#ifdef HEMM_INSTALL_DATA_DIR
  in.install_data_dir = HEMM_INSTALL_DATA_DIR;
#endif
  return in;
}

std::string find_data_file(const std::string& relative, const DataDirInputs& in) {
  for (const std::string& dir : data_dir_candidates(in)) {
    const std::filesystem::path p = std::filesystem::path(dir) / relative;
    std::error_code ec;
    if (std::filesystem::is_regular_file(p, ec)) return p.lexically_normal().string();
  }
  return {};
}

std::string find_data_file(const std::string& relative) {
  return find_data_file(relative, this_process_data_dir_inputs());
}

std::string default_config_path(const std::string& name, std::vector<std::string>* searched) {
  const DataDirInputs in = this_process_data_dir_inputs();
  if (searched != nullptr) *searched = data_dir_candidates(in);
  return find_data_file("configs/" + name, in);
}

}  // namespace hemm::config
