// A window (GLFW) drawn by MuJoCo 2.2.2's renderer (mjv/mjr), shared by the
// live views of both stations: the model's own scene plus extra primitives,
// overlay text and coloured banners; the camera moves with the mouse as in
// MuJoCo's viewer (left drag: rotate, right drag: move, middle drag or
// scroll: zoom; with Shift the horizontal-plane variants); keys are handed to
// the caller. Hidden windows render to MuJoCo's offscreen buffer, for PNGs
// without a visible window (still an X display: Xvfb on servers).
//
// MuJoCo and GLFW stay in the .cpp (pimpl). Threads: every call, including
// construction and destruction, on one thread (the view's); GLFW is used only
// by that thread (on X11 it need not be the process's main thread, which here
// runs the network).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "common/sim/mujoco_owner.h"
#include "common/view/png_io.h"
#include "common/view/primitives.h"

namespace hemm::view {

// A view's own MuJoCo model and data (common/sim/mujoco_owner.h; its
// load_model_xml / load_model_file make the model).
using sim::MjDataPtr;
using sim::MjModelPtr;
// sim::make_data + mj_forward: the model at rest, ready to draw.
MjDataPtr make_data(mjModel_* m);

struct WindowOptions {
  bool visible = true;
  int width = 640;
  int height = 480;
  std::string title = "hemm";
  int extra_geoms = 6000;  // room for primitives beyond the model's own geoms
};

class MujocoWindow {
 public:
  // Opens the window and MuJoCo's render context for `m` (whose offscreen
  // size and render quality it adjusts: no multisampling, no shadow map, for
  // software OpenGL). `m` and `d` must outlive the window. Throws
  // std::runtime_error with a one-line reason (no display, no OpenGL).
  MujocoWindow(mjModel_* m, mjData_* d, const WindowOptions& o);
  ~MujocoWindow();
  MujocoWindow(const MujocoWindow&) = delete;
  MujocoWindow& operator=(const MujocoWindow&) = delete;

  CameraSpec camera() const;
  void set_camera(const CameraSpec& c);
  // Keeps distance and angles (the user's), moves what the camera looks at.
  void set_lookat(const Eigen::Vector3d& p);
  double fovy_deg() const;  // the model's vertical field of view

  // Handles window events (mouse, keys, close). Call once per loop.
  void poll();
  // Keys pressed since the last call (GLFW key codes: letters 'A'..'Z', digits).
  std::vector<int> take_keys();
  bool close_requested() const;

  // One frame: the model's scene at d (mjv_updateScene), then `extra`, then
  // the overlay; shown when visible. With capture, also reads the frame's
  // pixels into it. Returns how many extra primitives did not fit.
  std::size_t render(const std::vector<Primitive>& extra, const Overlay& overlay, Image* capture);

  int width() const;   // framebuffer size of the frames rendered
  int height() const;
  std::string gl_renderer() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hemm::view
