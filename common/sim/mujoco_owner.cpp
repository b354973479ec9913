#include "common/sim/mujoco_owner.h"

#include <mujoco/mujoco.h>

#include <cstring>
#include <stdexcept>

namespace hemm::sim {

void MjModelDeleter::operator()(mjModel* m) const { mj_deleteModel(m); }
void MjDataDeleter::operator()(mjData* d) const { mj_deleteData(d); }

MjModelPtr load_model_file(const std::string& path) {
  char err[1000] = "";
  mjModel* m = mj_loadXML(path.c_str(), nullptr, err, sizeof err);
  if (m == nullptr) throw std::runtime_error(path + ": " + err);
  return MjModelPtr(m);
}

MjModelPtr load_model_xml(const std::string& name, const std::string& xml) {
  // On the heap: mjVFS holds 2000 file slots (about 4 MB with their names).
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), name.c_str(), static_cast<int>(xml.size())) != 0) {
    mj_deleteVFS(vfs.get());
    throw std::runtime_error(name + ": MuJoCo's virtual file system is full");
  }
  const int i = mj_findFileVFS(vfs.get(), name.c_str());
  std::memcpy(vfs->filedata[i], xml.data(), xml.size());
  char err[1000] = "";
  mjModel* m = mj_loadXML(name.c_str(), vfs.get(), err, sizeof err);
  mj_deleteVFS(vfs.get());
  if (m == nullptr) throw std::runtime_error(name + ": " + err);
  return MjModelPtr(m);
}

MjDataPtr make_data(const mjModel* m) {
  MjDataPtr d(mj_makeData(m));
  if (!d) throw std::runtime_error("MuJoCo could not allocate the model's data (mj_makeData)");
  return d;
}

MujocoOwner::MujocoOwner(MjModelPtr model) : model_(std::move(model)) {
  if (model_) data_ = make_data(model_.get());
}

}  // namespace hemm::sim
