#include "common/view/mujoco_window.h"

#include <GLFW/glfw3.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

namespace hemm::view {
namespace {

// GLFW reports errors through a callback; keep the last one for the message
// of the exception (the view thread is GLFW's only user).
thread_local std::string g_glfw_error;
void on_glfw_error(int code, const char* what) { g_glfw_error = std::to_string(code) + ": " + (what ? what : ""); }

int to_mj_type(Shape s) {
  switch (s) {
    case Shape::kBox: return mjGEOM_BOX;
    case Shape::kSphere: return mjGEOM_SPHERE;
    case Shape::kCylinder: return mjGEOM_CYLINDER;
    case Shape::kArrow: return mjGEOM_ARROW;
    case Shape::kLine: return mjGEOM_LINE;
    case Shape::kCapsule: return mjGEOM_CAPSULE;
  }
  return mjGEOM_BOX;
}

}  // namespace

MjDataPtr make_data(mjModel* m) {
  MjDataPtr d = sim::make_data(m);
  mj_forward(m, d.get());
  return d;
}

struct MujocoWindow::Impl {
  mjModel* m = nullptr;
  mjData* d = nullptr;
  WindowOptions o;
  GLFWwindow* window = nullptr;
  bool glfw_up = false;
  mjvScene scn;
  mjrContext con;
  mjvCamera cam;
  mjvOption opt;
  bool scene_made = false, context_made = false;
  // Mouse state (GLFW callbacks).
  bool left = false, right = false, middle = false;
  double last_x = 0, last_y = 0;
  std::vector<int> keys;
  int fb_w = 0, fb_h = 0;
  std::unique_ptr<mjvFigure> figure;  // ~800 kB: made on the first plot

  ~Impl() {
    if (context_made) mjr_freeContext(&con);
    if (scene_made) mjv_freeScene(&scn);
    if (window != nullptr) glfwDestroyWindow(window);
    if (glfw_up) glfwTerminate();
  }

  static Impl* self(GLFWwindow* w) { return static_cast<Impl*>(glfwGetWindowUserPointer(w)); }

  static void on_key(GLFWwindow* w, int key, int, int action, int mods) {
    if (action != GLFW_PRESS) return;
    Impl* s = self(w);
    // Shift with a letter: the caller sees it as a distinct code (lowercase
    // stays the key, uppercase is Shift+key), e.g. 'e' e-stop, 'E'...
    if (key >= GLFW_KEY_A && key <= GLFW_KEY_Z && !(mods & GLFW_MOD_SHIFT)) key = key - 'A' + 'a';
    s->keys.push_back(key);
  }
  static void on_button(GLFWwindow* w, int, int, int) {
    Impl* s = self(w);
    s->left = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    s->right = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
    s->middle = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    glfwGetCursorPos(w, &s->last_x, &s->last_y);
  }
  static void on_move(GLFWwindow* w, double x, double y) {
    Impl* s = self(w);
    const double dx = x - s->last_x, dy = y - s->last_y;
    s->last_x = x;
    s->last_y = y;
    if (!s->left && !s->right && !s->middle) return;
    int width = 0, height = 0;
    glfwGetWindowSize(w, &width, &height);
    if (height <= 0) return;
    const bool shift = glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                       glfwGetKey(w, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS;
    int action = mjMOUSE_ZOOM;
    if (s->right) action = shift ? mjMOUSE_MOVE_H : mjMOUSE_MOVE_V;
    else if (s->left) action = shift ? mjMOUSE_ROTATE_H : mjMOUSE_ROTATE_V;
    mjv_moveCamera(s->m, action, dx / height, dy / height, &s->scn, &s->cam);
  }
  static void on_scroll(GLFWwindow* w, double, double yoffset) {
    Impl* s = self(w);
    mjv_moveCamera(s->m, mjMOUSE_ZOOM, 0, -0.05 * yoffset, &s->scn, &s->cam);
  }
};

MujocoWindow::MujocoWindow(mjModel_* m, mjData_* d, const WindowOptions& o) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  if (m == nullptr || d == nullptr) throw std::invalid_argument("MujocoWindow: no model");
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192)
    throw std::invalid_argument("MujocoWindow: size outside 16..8192");
  s.m = m;
  s.d = d;
  s.o = o;
  glfwSetErrorCallback(on_glfw_error);
  if (!glfwInit()) throw std::runtime_error("cannot start GLFW (no X display? set DISPLAY or run under Xvfb): " + g_glfw_error);
  s.glfw_up = true;
  glfwWindowHint(GLFW_VISIBLE, o.visible ? GLFW_TRUE : GLFW_FALSE);
  glfwWindowHint(GLFW_SAMPLES, 0);
  glfwWindowHint(GLFW_DOUBLEBUFFER, GLFW_TRUE);
  s.window = glfwCreateWindow(o.width, o.height, o.title.c_str(), nullptr, nullptr);
  if (s.window == nullptr) throw std::runtime_error("cannot open a window with OpenGL: " + g_glfw_error);
  glfwMakeContextCurrent(s.window);
  glfwSwapInterval(0);  // never wait for a vertical retrace: the view paces itself
  glfwSetWindowUserPointer(s.window, &s);
  glfwSetKeyCallback(s.window, Impl::on_key);
  glfwSetMouseButtonCallback(s.window, Impl::on_button);
  glfwSetCursorPosCallback(s.window, Impl::on_move);
  glfwSetScrollCallback(s.window, Impl::on_scroll);

  // Software OpenGL (llvmpipe) on a 2-core machine: no multisampling, no
  // shadow map; the offscreen buffer is the picture size.
  m->vis.global.offwidth = o.width;
  m->vis.global.offheight = o.height;
  m->vis.quality.offsamples = 0;
  m->vis.quality.shadowsize = 0;
  mjv_defaultScene(&s.scn);
  mjv_makeScene(m, &s.scn, m->ngeom + o.extra_geoms + 100);
  s.scene_made = true;
  s.scn.flags[mjRND_SHADOW] = 0;
  s.scn.flags[mjRND_REFLECTION] = 0;
  s.scn.flags[mjRND_SKYBOX] = 0;
  mjr_defaultContext(&s.con);
  mjr_makeContext(m, &s.con, mjFONTSCALE_100);
  s.context_made = true;
  if (s.con.offWidth < o.width || s.con.offHeight < o.height) throw std::runtime_error("offscreen buffer too small");
  mjv_defaultCamera(&s.cam);
  mjv_defaultOption(&s.opt);
  s.opt.flags[mjVIS_RANGEFINDER] = 0;
  s.opt.geomgroup[3] = 1;  // hemm's robot geoms (group 3: the range sensors' rays skip it)
}

MujocoWindow::~MujocoWindow() = default;

CameraSpec MujocoWindow::camera() const {
  const mjvCamera& c = impl_->cam;
  CameraSpec out;
  out.lookat = Eigen::Vector3d(c.lookat[0], c.lookat[1], c.lookat[2]);
  out.distance = c.distance;
  out.azimuth = c.azimuth;
  out.elevation = c.elevation;
  return out;
}

void MujocoWindow::set_camera(const CameraSpec& c) {
  mjvCamera& cam = impl_->cam;
  cam.type = mjCAMERA_FREE;
  for (int i = 0; i < 3; ++i) cam.lookat[i] = c.lookat[i];
  cam.distance = c.distance;
  cam.azimuth = c.azimuth;
  cam.elevation = c.elevation;
}

void MujocoWindow::set_lookat(const Eigen::Vector3d& p) {
  for (int i = 0; i < 3; ++i) impl_->cam.lookat[i] = p[i];
}

double MujocoWindow::fovy_deg() const { return impl_->m->vis.global.fovy; }

void MujocoWindow::poll() { glfwPollEvents(); }

std::vector<int> MujocoWindow::take_keys() {
  std::vector<int> out;
  out.swap(impl_->keys);
  return out;
}

bool MujocoWindow::close_requested() const { return glfwWindowShouldClose(impl_->window) != 0; }

std::size_t MujocoWindow::render(const std::vector<Primitive>& extra, const Overlay& overlay, Image* capture) {
  Impl& s = *impl_;
  mjv_updateScene(s.m, s.d, &s.opt, nullptr, &s.cam, mjCAT_ALL, &s.scn);
  std::size_t dropped = 0;
  for (const Primitive& p : extra) {
    if (s.scn.ngeom >= s.scn.maxgeom) {
      ++dropped;
      continue;
    }
    mjvGeom* g = &s.scn.geoms[s.scn.ngeom];
    const float rgba[4] = {p.rgba.r, p.rgba.g, p.rgba.b, p.rgba.a};
    const mjtNum pos[3] = {p.pos.x(), p.pos.y(), p.pos.z()};
    if (p.shape == Shape::kArrow || p.shape == Shape::kLine || p.shape == Shape::kCapsule) {
      mjv_initGeom(g, to_mj_type(p.shape), nullptr, nullptr, nullptr, rgba);
      mjv_makeConnector(g, to_mj_type(p.shape), p.width, p.pos.x(), p.pos.y(), p.pos.z(), p.to.x(), p.to.y(),
                        p.to.z());
    } else {
      const mjtNum size[3] = {p.size.x(), p.size.y(), p.size.z()};
      mjtNum mat[9];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) mat[3 * i + j] = p.R(i, j);  // row-major
      mjv_initGeom(g, to_mj_type(p.shape), size, pos, mat, rgba);
    }
    g->category = mjCAT_DECOR;
    g->specular = 0.0f;  // flat colours: a highlight would wash a marker out
    g->emission = 0.25f;
    ++s.scn.ngeom;
  }

  if (s.o.visible) {
    glfwGetFramebufferSize(s.window, &s.fb_w, &s.fb_h);
    mjr_setBuffer(mjFB_WINDOW, &s.con);
  } else {
    s.fb_w = s.o.width;
    s.fb_h = s.o.height;
    mjr_setBuffer(mjFB_OFFSCREEN, &s.con);
  }
  const mjrRect vp = {0, 0, s.fb_w, s.fb_h};
  mjr_render(vp, &s.scn, &s.con);
  if (!overlay.left.empty() || !overlay.right.empty())
    mjr_overlay(mjFONT_NORMAL, mjGRID_TOPLEFT, vp, overlay.left.c_str(), overlay.right.c_str(), &s.con);
  if (!overlay.bottom.empty()) mjr_overlay(mjFONT_NORMAL, mjGRID_BOTTOMLEFT, vp, overlay.bottom.c_str(), nullptr, &s.con);
  const bool has_points = std::any_of(overlay.plot.lines.begin(), overlay.plot.lines.end(),
                                      [](const PlotLine& l) { return !l.x.empty(); });
  if (has_points) {
    if (!s.figure) s.figure = std::make_unique<mjvFigure>();
    mjvFigure& f = *s.figure;
    mjv_defaultFigure(&f);
    std::snprintf(f.title, sizeof f.title, "%s", overlay.plot.title.c_str());
    std::snprintf(f.xlabel, sizeof f.xlabel, "%s", overlay.plot.xlabel.c_str());
    f.flg_legend = 1;
    f.figurergba[3] = 0.6f;
    f.range[0][0] = overlay.plot.x_min;
    f.range[0][1] = overlay.plot.x_max;
    const int n = std::min<int>(static_cast<int>(overlay.plot.lines.size()), 8);
    for (int i = 0; i < n; ++i) {
      const PlotLine& l = overlay.plot.lines[static_cast<std::size_t>(i)];
      const int pts = std::min<int>(static_cast<int>(std::min(l.x.size(), l.y.size())), mjMAXLINEPNT);
      std::snprintf(f.linename[i], sizeof f.linename[i], "%s", l.name.c_str());
      f.linergb[i][0] = l.colour.r;
      f.linergb[i][1] = l.colour.g;
      f.linergb[i][2] = l.colour.b;
      for (int k = 0; k < pts; ++k) {
        f.linedata[i][2 * k] = l.x[static_cast<std::size_t>(k)];
        f.linedata[i][2 * k + 1] = l.y[static_cast<std::size_t>(k)];
      }
      f.linepnt[i] = pts;
    }
    // The bottom right corner, small: the scene's middle stays in view.
    const int w = std::max(200, s.fb_w * 8 / 25), h = std::max(130, s.fb_h * 7 / 25);
    mjr_figure(mjrRect{s.fb_w - w, 30, w, h}, &f, &s.con);
  }
  int top = s.fb_h;
  for (const Banner& b : overlay.banners) {
    const int w = 24 + 9 * static_cast<int>(b.text.size()), h = 26;
    top -= h + 6;
    const mjrRect r = {s.fb_w - w - 6, top, w, h};
    mjr_label(r, mjFONT_NORMAL, b.text.c_str(), b.colour.r, b.colour.g, b.colour.b, 0.9f, 1, 1, 1, &s.con);
  }
  if (capture != nullptr && s.fb_w > 0 && s.fb_h > 0) {
    capture->width = s.fb_w;
    capture->height = s.fb_h;
    const std::size_t row = static_cast<std::size_t>(s.fb_w) * 3;
    capture->rgb.resize(row * s.fb_h);
    mjr_readPixels(capture->rgb.data(), nullptr, vp, &s.con);
    // OpenGL's rows come bottom first; images are top first.
    std::vector<std::uint8_t> tmp(row);
    for (int y = 0; y < s.fb_h / 2; ++y) {
      std::uint8_t* a = capture->rgb.data() + row * y;
      std::uint8_t* b = capture->rgb.data() + row * (s.fb_h - 1 - y);
      std::memcpy(tmp.data(), a, row);
      std::memcpy(a, b, row);
      std::memcpy(b, tmp.data(), row);
    }
  }
  if (s.o.visible) glfwSwapBuffers(s.window);
  return dropped;
}

int MujocoWindow::width() const { return impl_->fb_w; }
int MujocoWindow::height() const { return impl_->fb_h; }

std::string MujocoWindow::gl_renderer() const {
  const GLubyte* r = glGetString(GL_RENDERER);
  return r != nullptr ? reinterpret_cast<const char*>(r) : "unknown";
}

}  // namespace hemm::view
