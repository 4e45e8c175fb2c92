#include "tools/report/render.h"

#include <GL/gl.h>
#include <GL/osmesa.h>
#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/asan.h"
#include "core/mujoco_env.h"

#ifdef MJSYSID_ASAN
// In sanitizer builds: OSMesa (Mesa 22.3) keeps the framebuffer it makes for each context in a
// global list that it never frees (not even when the context is released and destroyed, tested),
// ~260 bytes per renderer; LeakSanitizer is told to skip what libOSMesa allocates, and sees the
// rest. (The sanitizer runtime calls this hook; one definition per program.)
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\n"; }
#endif

namespace mjsysid::report {
namespace {

// libOSMesa loaded at run time, not linked: a program or Python package without it runs, and
// only the motion clip is skipped (Create says why). RTLD_LOCAL: its libLLVM's symbols must not
// become global (PyTorch's triton, which carries its own LLVM, crashed on import in its static
// initializers after a global load; measured in tests/python); mjr_makeContext finds the GL
// functions without it (tests/tools/render_test.cc). Loaded once per process, never unloaded.
struct OsMesa {
  decltype(&OSMesaCreateContextExt) create_context = nullptr;
  decltype(&OSMesaMakeCurrent) make_current = nullptr;
  decltype(&OSMesaDestroyContext) destroy_context = nullptr;
  decltype(&glGetString) get_string = nullptr;
  std::string error;  // "": loaded
};

template <typename F>
void Symbol(void* library, const char* name, F* f, std::string* error) {
  *f = reinterpret_cast<F>(dlsym(library, name));
  if (*f == nullptr && error->empty()) *error = std::string("libOSMesa has no ") + name;
}

const OsMesa& LoadOsMesa() {
  static const OsMesa api = [] {
    OsMesa a;
    void* library = dlopen(kOsMesaLibrary, RTLD_NOW | RTLD_LOCAL);
    if (library == nullptr) {
      const char* why = dlerror();
      a.error = std::string("cannot load ") + kOsMesaLibrary + " (" +
                (why != nullptr ? why : "not found") +
                "; Debian and Ubuntu: apt install libosmesa6)";
      return a;
    }
    Symbol(library, "OSMesaCreateContextExt", &a.create_context, &a.error);
    Symbol(library, "OSMesaMakeCurrent", &a.make_current, &a.error);
    Symbol(library, "OSMesaDestroyContext", &a.destroy_context, &a.error);
    Symbol(library, "glGetString", &a.get_string, &a.error);
    return a;
  }();
  return api;
}

}  // namespace

// the OpenGL context and MuJoCo's visualization state, one model copy
struct OffscreenRenderer::Gl {
  OSMesaContext context = nullptr;
  int width = 0, height = 0;
  std::vector<uint8_t> window;  // OSMesa's default framebuffer (RGBA); MuJoCo draws into its FBO
  ModelPtr model;
  DataPtr data;
  mjvScene scene;
  mjvCamera camera;
  mjvOption option;
  mjrContext con;
  bool scene_made = false, con_made = false;

  ~Gl() {
    if (context != nullptr) {
      // MuJoCo's GL objects need the context current; then release it before destroying it
      // (OSMesa frees the framebuffer it made for the window only when it is released)
      const OsMesa& gl = LoadOsMesa();
      if (con_made && gl.make_current(context, window.data(), GL_UNSIGNED_BYTE, width, height)) {
        mjr_freeContext(&con);
      }
      gl.make_current(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0);
      gl.destroy_context(context);
    }
    if (scene_made) mjv_freeScene(&scene);
  }
};

std::unique_ptr<OffscreenRenderer> OffscreenRenderer::Create(const mjModel& m, int width,
                                                             int height, std::string* why) {
  if (width < 1 || height < 1) throw std::invalid_argument("renderer size must be positive");
  InstallMujocoHandlers();
  std::unique_ptr<OffscreenRenderer> r(new OffscreenRenderer());
  r->width_ = width;
  r->height_ = height;
  r->gl_ = std::make_unique<Gl>();
  Gl& g = *r->gl_;

  // the software context: RGBA, 24-bit depth, 8-bit stencil, no accumulation buffer
  const OsMesa& gl = LoadOsMesa();
  if (!gl.error.empty()) {
    if (why != nullptr) *why = gl.error;
    return nullptr;
  }
  g.context = gl.create_context(OSMESA_RGBA, 24, 8, 0, nullptr);
  if (g.context == nullptr) {
    if (why != nullptr) *why = "OSMesa could not create an OpenGL context";
    return nullptr;
  }
  g.window.assign(static_cast<size_t>(width) * height * 4, 0);
  g.width = width;
  g.height = height;
  if (!gl.make_current(g.context, g.window.data(), GL_UNSIGNED_BYTE, width, height)) {
    if (why != nullptr) *why = "OSMesa could not make its OpenGL context current";
    return nullptr;
  }
  const auto* name = reinterpret_cast<const char*>(gl.get_string(GL_RENDERER));
  r->gl_renderer_ = name != nullptr ? name : "";

  // the model copy with an offscreen buffer large enough; scene, camera, options
  g.model = CopyModel(m);
  g.model->vis.global.offwidth = std::max(g.model->vis.global.offwidth, width);
  g.model->vis.global.offheight = std::max(g.model->vis.global.offheight, height);
  // a 1024 shadow map instead of MuJoCo's 4096: the clip is 320x240, and the software rasterizer
  // spends most of a frame on the map otherwise
  g.model->vis.quality.shadowsize = std::min(g.model->vis.quality.shadowsize, 1024);
  // a brighter headlight than MuJoCo's default (ambient 0.1, diffuse 0.4): most models have no
  // lights of their own, and the clip is small
  for (int i = 0; i < 3; ++i) {
    g.model->vis.headlight.ambient[i] = std::max(g.model->vis.headlight.ambient[i], 0.35f);
    g.model->vis.headlight.diffuse[i] = std::max(g.model->vis.headlight.diffuse[i], 0.7f);
  }
  g.data = MakeData(*g.model);
  mjv_defaultScene(&g.scene);
  mjv_defaultCamera(&g.camera);
  mjv_defaultOption(&g.option);
  mjr_defaultContext(&g.con);
  mjModel* model = g.model.get();
  try {
    CallMujoco([&] {
      mjv_makeScene(model, &g.scene, 2000);
      g.scene_made = true;
      mjv_defaultFreeCamera(model, &g.camera);
      mjr_makeContext(model, &g.con, mjFONTSCALE_100);
      g.con_made = true;
      mjr_setBuffer(mjFB_OFFSCREEN, &g.con);
    });
  } catch (const MujocoError& e) {
    if (why != nullptr) *why = std::string("MuJoCo could not use the OpenGL context: ") + e.what();
    return nullptr;
  }
  if (g.con.currentBuffer != mjFB_OFFSCREEN) {
    if (why != nullptr) *why = "the OpenGL context has no offscreen framebuffer";
    return nullptr;
  }
  return r;
}

OffscreenRenderer::~OffscreenRenderer() = default;

void OffscreenRenderer::MakeCurrent() {
  if (!LoadOsMesa().make_current(gl_->context, gl_->window.data(), GL_UNSIGNED_BYTE, width_,
                                 height_)) {
    throw MujocoError("OSMesa could not make its OpenGL context current");
  }
}

void OffscreenRenderer::Frame(const Eigen::Ref<const RowMatrix>& qpos) {
  Gl& g = *gl_;
  const mjModel* m = g.model.get();
  if (qpos.cols() != m->nq) {
    throw std::invalid_argument("Frame: qpos has " + std::to_string(qpos.cols()) +
                                " columns, the model nq = " + std::to_string(m->nq));
  }
  // the bounding box of the moving geoms' bounding spheres over the configurations
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(mjMAXVAL), hi = -lo;
  mjData* d = g.data.get();
  for (Eigen::Index k = 0; k < qpos.rows(); ++k) {
    const double* q = qpos.row(k).data();
    CallMujoco([&] {
      mju_copy(d->qpos, q, m->nq);
      mj_kinematics(m, d);
    });
    for (int i = 0; i < m->ngeom; ++i) {
      if (m->geom_bodyid[i] == 0 || m->geom_type[i] == mjGEOM_PLANE) continue;
      const Eigen::Vector3d c(d->geom_xpos + 3 * i);
      const Eigen::Vector3d r = Eigen::Vector3d::Constant(m->geom_rbound[i]);
      lo = lo.cwiseMin(c - r);
      hi = hi.cwiseMax(c + r);
    }
  }
  if (!(lo.array() <= hi.array()).all()) return;  // no moving geoms: MuJoCo's default stays
  // the camera: at the box's center, its sphere in the vertical field of view
  const Eigen::Vector3d center = (lo + hi) / 2;
  const double radius = std::max((hi - lo).norm() / 2, 1e-3);
  const double half_fovy = m->vis.global.fovy * mjPI / 360;
  for (int i = 0; i < 3; ++i) g.camera.lookat[i] = center[i];
  g.camera.distance = radius / std::sin(half_fovy) * 1.1;
}

void OffscreenRenderer::Render(const Eigen::Ref<const Eigen::VectorXd>& qpos,
                               const std::string& label, RgbImage* out) {
  Gl& g = *gl_;
  const mjModel* m = g.model.get();
  if (qpos.size() != m->nq) {
    throw std::invalid_argument("Render: qpos has " + std::to_string(qpos.size()) +
                                " values, the model nq = " + std::to_string(m->nq));
  }
  MakeCurrent();
  out->width = width_;
  out->height = height_;
  out->rgb.resize(static_cast<size_t>(width_) * height_ * 3);
  flipped_.resize(out->rgb.size());

  // the configuration at rest (positions only), its scene, drawn and read back
  mjData* d = g.data.get();
  const double* q = qpos.data();
  const char* text = label.c_str();
  uint8_t* pixels = flipped_.data();
  const mjrRect viewport = {0, 0, width_, height_};
  CallMujoco([&] {
    mju_copy(d->qpos, q, m->nq);
    mju_zero(d->qvel, m->nv);
    if (m->na > 0) mju_zero(d->act, m->na);
    d->time = 0;
    mj_forward(m, d);
    mjv_updateScene(m, d, &g.option, nullptr, &g.camera, mjCAT_ALL, &g.scene);
    mjr_render(viewport, &g.scene, &g.con);
    if (text[0] != '\0') {
      mjr_overlay(mjFONT_BIG, mjGRID_TOPLEFT, viewport, text, nullptr, &g.con);
    }
    mjr_readPixels(pixels, nullptr, viewport, &g.con);
  });

  // OpenGL's rows start at the bottom
  const size_t row = static_cast<size_t>(width_) * 3;
  for (int y = 0; y < height_; ++y) {
    std::copy_n(flipped_.data() + (height_ - 1 - y) * row, row, out->rgb.data() + y * row);
  }
}

}  // namespace mjsysid::report
