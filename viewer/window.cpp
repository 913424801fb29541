#include "viewer/window.h"

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>
#include <vector>

// AddressSanitizer: GCC defines __SANITIZE_ADDRESS__, clang has __has_feature(address_sanitizer).
#if defined(__SANITIZE_ADDRESS__)
#define GENSCENE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define GENSCENE_ASAN 1
#endif
#endif
#if defined(GENSCENE_ASAN)
#include <dlfcn.h>
#include <link.h>
#endif

#include "core/image_io.h"

namespace genscene::viewer {

namespace {

std::string& LastGlfwError() {
  static std::string message;
  return message;
}

void OnGlfwError(int code, const char* description) {
  LastGlfwError() =
      Format(description ? description : "unknown", " (GLFW error 0x", std::hex, code, ")");
}

// Under AddressSanitizer only: keeps Mesa's DRI driver (*_dri.so) loaded until the process ends.
// XCloseDisplay (glfwTerminate) unloads it while its globals still point to its allocations, which
// LeakSanitizer then reports as leaks from an "<unknown module>" that no suppression can name.
void PinGlDriverForLeakSanitizer() {
#if defined(GENSCENE_ASAN)
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void*) -> int {
        const std::string name = info->dlpi_name ? info->dlpi_name : "";
        if (name.size() > 7 && name.compare(name.size() - 7, 7, "_dri.so") == 0) {
          dlopen(name.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        }
        return 0;
      },
      nullptr);
#endif
}

// glfwInit / glfwTerminate and one window with a current OpenGL 3.3 core context.
class GlfwWindow {
 public:
  GlfwWindow(int width, int height, const std::string& title, bool visible) {
    glfwSetErrorCallback(OnGlfwError);
    if (glfwInit() != GLFW_TRUE) {
      throw NoDisplayError(Format("no display: ", LastGlfwError()));
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
    window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
    if (!window_) {
      const std::string why = LastGlfwError();
      glfwTerminate();
      throw Error(Format("viewer: cannot open an OpenGL 3.3 core window: ", why));
    }
    glfwMakeContextCurrent(window_);
    PinGlDriverForLeakSanitizer();
  }
  ~GlfwWindow() {
    glfwDestroyWindow(window_);
    glfwTerminate();
  }
  GLFWwindow* get() const { return window_; }

 private:
  GLFWwindow* window_ = nullptr;
};

// Interaction state shared with the GLFW callbacks (through the window user pointer).
struct Session {
  Renderer* renderer = nullptr;
  const ViewData* data = nullptr;
  PosedView view;         // what is drawn
  OrbitController orbit;  // takes over from `view` at the first drag or scroll
  bool orbiting = false;
  DrawOptions options;
  int keyframe = -1;  // the keyframe whose camera is shown, -1 = none
  double last_x = 0.0, last_y = 0.0;
  bool dragging_rotate = false, dragging_pan = false;

  void StartOrbit() {
    if (orbiting) return;
    const Eigen::AlignedBox3d bounds = renderer->Bounds();
    const double distance =
        bounds.isEmpty() ? 3.0 : (bounds.center() - view.world_from_camera.translation()).norm();
    orbit = OrbitController::FromPose(view.world_from_camera, distance, WorkspaceUp(*data));
    orbiting = true;
    keyframe = -1;
  }
  void UpdateTitle(GLFWwindow* window) const {
    const std::string title =
        Format("genscene-view: ", ColorModeName(options.mode),
               renderer->Supports(options.mode) ? "" : " (not in this workspace: geometry)",
               options.lookup == Lookup::kNearest ? ", nearest" : ", linear",
               keyframe >= 0 ? Format(", keyframe ", keyframe) : std::string(), "  |  H: help");
    glfwSetWindowTitle(window, title.c_str());
  }
};

Session* SessionOf(GLFWwindow* window) {
  return static_cast<Session*>(glfwGetWindowUserPointer(window));
}

void OnKey(GLFWwindow* window, int key, int, int action, int) {
  if (action != GLFW_PRESS) return;
  Session& s = *SessionOf(window);
  switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q:
      glfwSetWindowShouldClose(window, GLFW_TRUE);
      break;
    case GLFW_KEY_1:
      s.options.mode = ColorMode::kObserved;
      break;
    case GLFW_KEY_2:
      s.options.mode = ColorMode::kAlbedo;
      break;
    case GLFW_KEY_3:
      s.options.mode = ColorMode::kShading;
      break;
    case GLFW_KEY_4:
      s.options.mode = ColorMode::kClusters;
      break;
    case GLFW_KEY_5:
      s.options.mode = ColorMode::kGeometry;
      break;
    case GLFW_KEY_L:
      s.options.lookup = s.options.lookup == Lookup::kNearest ? Lookup::kLinear : Lookup::kNearest;
      break;
    case GLFW_KEY_B:
      s.options.cull_back_faces = !s.options.cull_back_faces;
      break;
    case GLFW_KEY_O:
      s.options.show_overlay = !s.options.show_overlay;
      break;
    case GLFW_KEY_R:
      s.options.show_refined = !s.options.show_refined;
      if (!s.renderer->HasRefinedMesh())
        std::printf("genscene-view: no mesh_refined.ply in this workspace\n");
      break;
    case GLFW_KEY_V:
      s.orbit = Overview(*s.data, s.view.intrinsics);
      s.orbiting = true;
      s.keyframe = -1;
      break;
    case GLFW_KEY_K:
    case GLFW_KEY_J: {
      const int n = static_cast<int>(s.data->keyframes.size());
      if (n == 0) {
        std::printf("genscene-view: no keyframes in this workspace\n");
        break;
      }
      s.keyframe = ((s.keyframe < 0 ? -1 : s.keyframe) + (key == GLFW_KEY_K ? 1 : n - 1)) % n;
      const PosedView& key_view = s.data->keyframes[s.keyframe];
      s.view.world_from_camera = key_view.world_from_camera;
      // Keep the window's size; take the keyframe's field of view.
      const double scale = static_cast<double>(s.view.intrinsics.width) / key_view.intrinsics.width;
      s.view.intrinsics.fx = key_view.intrinsics.fx * scale;
      s.view.intrinsics.fy = key_view.intrinsics.fy * scale;
      s.orbiting = false;
      break;
    }
    case GLFW_KEY_H:
      std::printf("%s", KeyHelp().c_str());
      break;
    default:
      return;
  }
  std::fflush(stdout);
  s.UpdateTitle(window);
}

void OnMouseButton(GLFWwindow* window, int button, int action, int mods) {
  Session& s = *SessionOf(window);
  const bool down = action == GLFW_PRESS;
  const bool pan = button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE ||
                   (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_SHIFT));
  if (pan) {
    s.dragging_pan = down;
  } else if (button == GLFW_MOUSE_BUTTON_LEFT) {
    s.dragging_rotate = down;
  }
  glfwGetCursorPos(window, &s.last_x, &s.last_y);
}

void OnCursor(GLFWwindow* window, double x, double y) {
  Session& s = *SessionOf(window);
  const double dx = x - s.last_x, dy = y - s.last_y;
  s.last_x = x;
  s.last_y = y;
  if (!s.dragging_rotate && !s.dragging_pan) return;
  s.StartOrbit();
  if (s.dragging_pan) {
    s.orbit.Pan(dx, dy, s.view.intrinsics.fx);
  } else {
    s.orbit.Rotate(dx, dy);
  }
  s.UpdateTitle(window);
}

void OnScroll(GLFWwindow* window, double, double y_steps) {
  Session& s = *SessionOf(window);
  s.StartOrbit();
  s.orbit.Zoom(y_steps);
  s.UpdateTitle(window);
}

}  // namespace

ImageRgb RenderScreenshot(const ViewData& data, const PosedView& view, const DrawOptions& options) {
  GlfwWindow window(view.intrinsics.width, view.intrinsics.height, "genscene-view", false);
  Renderer renderer(data);
  return renderer.RenderImage(view, options);
}

std::string KeyHelp() {
  return "genscene-view keys:\n"
         "  left drag: orbit   right/middle or shift+left drag: pan   scroll: zoom\n"
         "  1 observed colour   2 albedo   3 shading (observed / albedo)   4 clusters   5 "
         "geometry\n"
         "  L nearest/linear Mesh Colors lookup   B cull back faces   O trajectory/frusta/lights\n"
         "  R refined mesh   K/J next/previous keyframe camera   V overview   H this help   Q/Esc "
         "quit\n";
}

void RunInteractive(const ViewData& data, const PosedView& view, const DrawOptions& options) {
  GlfwWindow window(view.intrinsics.width, view.intrinsics.height, "genscene-view", true);
  Renderer renderer(data);
  Session session;
  session.renderer = &renderer;
  session.data = &data;
  session.view = view;
  session.options = options;
  session.options.encode_srgb = true;
  glfwSetWindowUserPointer(window.get(), &session);
  glfwSetKeyCallback(window.get(), OnKey);
  glfwSetMouseButtonCallback(window.get(), OnMouseButton);
  glfwSetCursorPosCallback(window.get(), OnCursor);
  glfwSetScrollCallback(window.get(), OnScroll);
  glfwSwapInterval(1);
  session.UpdateTitle(window.get());
  std::printf("%s", KeyHelp().c_str());
  std::fflush(stdout);

  while (!glfwWindowShouldClose(window.get())) {
    // Follow the framebuffer's size: same vertical field of view, centred principal point.
    int w = 0, h = 0;
    glfwGetFramebufferSize(window.get(), &w, &h);
    if (w > 0 && h > 0 &&
        (w != session.view.intrinsics.width || h != session.view.intrinsics.height)) {
      CameraIntrinsics& k = session.view.intrinsics;
      const double scale = static_cast<double>(h) / k.height;
      k.fx *= scale;
      k.fy *= scale;
      k.width = w;
      k.height = h;
      k.cx = 0.5 * (w - 1);
      k.cy = 0.5 * (h - 1);
    }
    if (session.orbiting) session.view.world_from_camera = session.orbit.WorldFromCamera();
    if (w > 0 && h > 0) renderer.Draw(session.view, session.options);
    glfwSwapBuffers(window.get());
    glfwWaitEventsTimeout(0.1);
  }
}

}  // namespace genscene::viewer
