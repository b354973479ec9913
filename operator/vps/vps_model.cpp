#include "operator/vps/vps_model.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "common/haptics/vps/cache.h"
#include "common/mesh/mesh_io.h"

namespace hemm::op {

namespace {

constexpr std::size_t kMaxFileBytes = std::size_t{4} << 30;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Voxmap (and pointshell when `shell`) of a validated mesh.
void build_structures(const mesh::TriangleMesh& m, const VpsMeshSpec& s, const Eigen::Vector3d& reference,
                      bool shell, vps::Voxmap* vm, vps::PointShell* ps) {
  vps::VoxmapParams vp;
  vp.voxel_size = s.voxel_size;
  vp.layers_in = vp.layers_out = s.layers;
  if (auto e = vps::build_voxmap(m, vp, vm, nullptr)) throw std::invalid_argument("voxmap: " + e->message);
  if (!shell) {
    ps->voxel_size = s.voxel_size;  // a scene has no pointshell
    return;
  }
  vps::PointShellParams pp;
  pp.voxel_size = s.shell_voxel > 0 ? s.shell_voxel : s.voxel_size;
  if (auto e = vps::build_pointshell(m, pp, reference, ps)) throw std::invalid_argument("pointshell: " + e->message);
}

void fill_object(const mesh::TriangleMesh& m, const VpsMeshSpec& s, VpsObjectModel* o) {
  mesh::TriangleMesh valid;
  mesh::MeshReport rep;
  if (auto e = mesh::validate_mesh(m, {}, &valid, &rep)) throw std::invalid_argument(e->message);
  if (!rep.watertight()) throw std::invalid_argument("a held object must be a closed mesh (mass, inside)");
  o->mass = mesh::compute_mass_properties(valid, s.density);
  if (s.mass > 0 && o->mass.mass > 0) {
    o->mass.inertia_com *= s.mass / o->mass.mass;
    o->mass.mass = s.mass;
  }
  o->triangles = valid.triangles.size();
}

void wire_up(VpsLocalModel* m, const vps::ContactParams& contact) {
  m->bimanual.scene = &m->scene;
  m->bimanual.params = contact;
  if (m->object_count > 0) m->bimanual.right = {&m->objects[0].voxmap, &m->objects[0].shell};
  if (m->object_count > 1) m->bimanual.left = {&m->objects[1].voxmap, &m->objects[1].shell};
}

void check_contact(const vps::ContactParams& c) {
  if (!(c.stiffness > 0) || !std::isfinite(c.stiffness)) throw std::invalid_argument("contact stiffness must be > 0");
}

// "<dir>/<stem>.v<voxel um>.s<shell um>.l<layers>.vps"
std::string cache_path(const VpsMeshSpec& s, const std::string& dir, bool shell) {
  namespace fs = std::filesystem;
  const fs::path mesh(s.mesh_path);
  const fs::path d = dir.empty() ? mesh.parent_path() : fs::path(dir);
  char tag[128];
  std::snprintf(tag, sizeof tag, ".v%ld.s%ld.l%d.x%g%s.vps", std::lround(s.voxel_size * 1e6),
                shell ? std::lround((s.shell_voxel > 0 ? s.shell_voxel : s.voxel_size) * 1e6) : 0L, s.layers, s.scale,
                shell ? "" : ".scene");
  return (d / (mesh.stem().string() + tag)).string();
}

bool cache_fresh(const std::string& cache, const std::string& mesh) {
  std::error_code e1, e2;
  const auto tc = std::filesystem::last_write_time(cache, e1);
  const auto tm = std::filesystem::last_write_time(mesh, e2);
  return !e1 && !e2 && tc >= tm;
}

// Loads the mesh (always for an object: its mass), then the cache if fresh and
// of the asked resolution, else builds and writes it.
void load_one(const VpsMeshSpec& s, const std::string& cache_dir, bool is_object, vps::Voxmap* vm,
              vps::PointShell* ps, VpsObjectModel* obj, std::size_t* triangles, VpsLoadReport* report) {
  if (const char* bad = check_mesh_spec(s)) throw std::runtime_error(s.mesh_path + ": " + bad);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string cache = cache_path(s, cache_dir, is_object);
  mesh::TriangleMesh m;
  bool have_mesh = false;
  auto load_mesh = [&] {
    mesh::LoadOptions lo;
    lo.scale = s.scale;
    mesh::MeshReport rep;
    if (auto e = mesh::load_mesh(s.mesh_path, lo, &m, &rep)) throw std::runtime_error(e->message);
    have_mesh = true;
    *triangles = m.triangles.size();
  };
  if (is_object) {
    load_mesh();
    try {
      fill_object(m, s, obj);
    } catch (const std::exception& e) {
      throw std::runtime_error(s.mesh_path + ": " + e.what());
    }
  }
  std::string why;
  if (cache_fresh(cache, s.mesh_path)) {
    vps::Voxmap cvm;
    vps::PointShell cps;
    if (!load_vps_file(cache, &cvm, &cps, &why)) {
      // fall through to a rebuild
    } else if (std::abs(cvm.voxel_size - s.voxel_size) > 1e-9 || cvm.layers_in != s.layers ||
               (is_object && cps.size() == 0)) {
      why = cache + ": another resolution";
    } else {
      *vm = std::move(cvm);
      *ps = std::move(cps);
      if (!is_object) *triangles = 0;  // not loaded: the cache stands for it
      if (report)
        report->lines.push_back(s.mesh_path + ": from cache " + cache + " (" +
                                std::to_string(vm->memory_bytes() / 1000) + " kB, " +
                                std::to_string(seconds_since(t0)) + " s)");
      return;
    }
    if (report) report->warnings.push_back(why + "; rebuilding");
  }
  if (!have_mesh) load_mesh();
  try {
    build_structures(m, s, is_object ? obj->mass.centre_of_mass : Eigen::Vector3d::Zero(), is_object, vm, ps);
  } catch (const std::exception& e) {
    throw std::runtime_error(s.mesh_path + ": " + e.what());
  }
  std::string err;
  if (!save_vps_file(cache, *vm, *ps, &err) && report) report->warnings.push_back("cache not written: " + err);
  if (report)
    report->lines.push_back(s.mesh_path + ": " + std::to_string(*triangles) + " triangles, built in " +
                            std::to_string(seconds_since(t0)) + " s (" + std::to_string(vm->memory_bytes() / 1000) +
                            " kB voxmap, " + std::to_string(ps->size()) + " shell points)");
}

}  // namespace

std::size_t VpsLocalModel::memory_bytes() const {
  std::size_t b = scene.memory_bytes();
  for (int k = 0; k < object_count; ++k) b += objects[k].voxmap.memory_bytes() + objects[k].shell.memory_bytes();
  return b;
}

const char* check_mesh_spec(const VpsMeshSpec& s) {
  if (!(s.voxel_size >= 1e-4 && s.voxel_size <= 1.0)) return "voxel size must be in [0.1 mm, 1 m]";
  if (!(s.shell_voxel == 0.0 || (s.shell_voxel >= 1e-4 && s.shell_voxel <= 1.0)))
    return "pointshell voxel size must be 0 (= voxel size) or in [0.1 mm, 1 m]";
  if (s.layers < 1 || s.layers > 100) return "layers must be in [1, 100]";
  if (!(s.scale > 0) || !std::isfinite(s.scale)) return "scale must be > 0";
  if (!(s.density > 0) || !std::isfinite(s.density)) return "density must be > 0";
  if (!(s.mass >= 0 && s.mass <= 1000)) return "mass must be in [0, 1000] kg";
  return nullptr;
}

std::shared_ptr<VpsLocalModel> make_vps_model(const mesh::TriangleMesh& scene, const VpsMeshSpec& scene_spec,
                                              const std::vector<std::pair<mesh::TriangleMesh, VpsMeshSpec>>& objects,
                                              const vps::ContactParams& contact) {
  check_contact(contact);
  if (objects.size() > static_cast<std::size_t>(device::kMaxEndEffectors))
    throw std::invalid_argument("more objects than end-effectors");
  auto m = std::make_shared<VpsLocalModel>();
  if (const char* bad = check_mesh_spec(scene_spec)) throw std::invalid_argument(std::string("scene: ") + bad);
  vps::PointShell none;
  build_structures(scene, scene_spec, Eigen::Vector3d::Zero(), false, &m->scene, &none);
  m->scene_triangles = scene.triangles.size();
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const auto& [mesh_k, spec] = objects[k];
    if (const char* bad = check_mesh_spec(spec)) throw std::invalid_argument("object " + std::to_string(k) + ": " + bad);
    VpsObjectModel& o = m->objects[k];
    fill_object(mesh_k, spec, &o);
    build_structures(mesh_k, spec, o.mass.centre_of_mass, true, &o.voxmap, &o.shell);
  }
  m->object_count = static_cast<int>(objects.size());
  wire_up(m.get(), contact);
  return m;
}

std::shared_ptr<VpsLocalModel> load_vps_model(const VpsModelSpec& spec, VpsLoadReport* report) {
  try {
    check_contact(spec.contact);
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what());
  }
  auto m = std::make_shared<VpsLocalModel>();
  vps::PointShell none;
  load_one(spec.scene, spec.cache_dir, false, &m->scene, &none, nullptr, &m->scene_triangles, report);
  int count = 0;
  for (std::size_t k = 0; k < spec.objects.size(); ++k) {
    if (!spec.objects[k]) break;  // objects fill end-effectors in order
    VpsObjectModel& o = m->objects[k];
    load_one(*spec.objects[k], spec.cache_dir, true, &o.voxmap, &o.shell, &o, &o.triangles, report);
    ++count;
  }
  m->object_count = count;
  wire_up(m.get(), spec.contact);
  return m;
}

bool read_file_bytes(const std::string& path, std::vector<std::uint8_t>* out, std::string* error) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) {
    *error = path + ": cannot open";
    return false;
  }
  const std::streamoff size = f.tellg();
  if (size < 0 || static_cast<std::size_t>(size) > kMaxFileBytes) {
    *error = path + ": cannot read or too large";
    return false;
  }
  out->resize(static_cast<std::size_t>(size));
  f.seekg(0);
  if (size > 0 && !f.read(reinterpret_cast<char*>(out->data()), size)) {
    *error = path + ": read error";
    return false;
  }
  return true;
}

bool load_vps_file(const std::string& path, vps::Voxmap* vm, vps::PointShell* ps, std::string* error) {
  std::vector<std::uint8_t> bytes;
  if (!read_file_bytes(path, &bytes, error)) return false;
  if (auto e = vps::deserialize_vps(bytes.data(), bytes.size(), vm, ps)) {
    *error = path + ": " + e->message;
    return false;
  }
  return true;
}

bool save_vps_file(const std::string& path, const vps::Voxmap& vm, const vps::PointShell& ps, std::string* error) {
  const auto bytes = vps::serialize_vps(vm, ps);
  // Written beside and renamed: a reader never sees half a cache.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f || !f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()))) {
      *error = tmp + ": cannot write";
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    *error = path + ": " + ec.message();
    return false;
  }
  return true;
}

}  // namespace hemm::op
