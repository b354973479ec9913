// One owner of a MuJoCo model and its data (MuJoCo 2.2.2), so that each
// place that loads a scene does not keep its own deleters. mujoco.h stays in
// the .cpp: MuJoCo's own struct tags (mjModel_, mjData_) are declared here,
// and a caller that steps the model includes <mujoco/mujoco.h> itself.
#pragma once

#include <memory>
#include <string>

struct mjModel_;
struct mjData_;

namespace hemm::sim {

struct MjModelDeleter {
  void operator()(mjModel_* m) const;
};
struct MjDataDeleter {
  void operator()(mjData_* d) const;
};
using MjModelPtr = std::unique_ptr<mjModel_, MjModelDeleter>;
using MjDataPtr = std::unique_ptr<mjData_, MjDataDeleter>;

// An MJCF file loaded; throws std::runtime_error "PATH: MuJoCo's message"
// if it does not load.
MjModelPtr load_model_file(const std::string& path);
// MJCF text loaded as an in-memory file called `name` (its includes and
// meshes are looked up beside it); throws std::runtime_error "NAME: MuJoCo's
// message" if it does not load.
MjModelPtr load_model_xml(const std::string& name, const std::string& xml);
// Fresh data for m (at its reference pose, no mj_forward yet); throws
// std::runtime_error if MuJoCo cannot allocate it.
MjDataPtr make_data(const mjModel_* m);

// A model with its data: a move-only value (the const model plus mutable
// data of MuJoCo's engine).
class MujocoOwner {
 public:
  MujocoOwner() = default;  // empty: m() and d() are null
  explicit MujocoOwner(MjModelPtr model);  // makes its data (throws as make_data)
  static MujocoOwner from_file(const std::string& path) { return MujocoOwner(load_model_file(path)); }
  static MujocoOwner from_xml(const std::string& name, const std::string& xml) {
    return MujocoOwner(load_model_xml(name, xml));
  }

  mjModel_* m() const { return model_.get(); }
  mjData_* d() const { return data_.get(); }
  explicit operator bool() const { return model_ != nullptr; }

 private:
  MjModelPtr model_;
  MjDataPtr data_;
};

}  // namespace hemm::sim
