#include "viewer/renderer.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <array>

#include "core/check.h"
#include "core/color.h"
#include "viewer/shaders.h"
#include "viewer/view_camera.h"

namespace genscene::viewer {

const char* ColorModeName(ColorMode mode) {
  switch (mode) {
    case ColorMode::kObserved:
      return "color";
    case ColorMode::kAlbedo:
      return "albedo";
    case ColorMode::kShading:
      return "shading";
    case ColorMode::kClusters:
      return "clusters";
    case ColorMode::kGeometry:
      return "geometry";
  }
  return "?";
}

ColorMode ParseColorMode(const std::string& text) {
  if (text == "color" || text == "observed") return ColorMode::kObserved;
  if (text == "albedo") return ColorMode::kAlbedo;
  if (text == "shading") return ColorMode::kShading;
  if (text == "clusters") return ColorMode::kClusters;
  if (text == "geometry") return ColorMode::kGeometry;
  throw Error(
      Format("--mode '", text, "' is not one of color, albedo, shading, clusters, geometry"));
}

namespace {

GLuint CompileShader(GLenum kind, const char* source, const char* name) {
  const GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    std::string log(4096, '\0');
    GLsizei length = 0;
    glGetShaderInfoLog(shader, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteShader(shader);
    throw Error(Format("viewer: shader ", name, " does not compile: ", log.substr(0, length)));
  }
  return shader;
}

GLuint LinkProgram(const char* vertex, const char* fragment, const char* name) {
  const GLuint vs = CompileShader(GL_VERTEX_SHADER, vertex, name);
  const GLuint fs = CompileShader(GL_FRAGMENT_SHADER, fragment, name);
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    std::string log(4096, '\0');
    GLsizei length = 0;
    glGetProgramInfoLog(program, static_cast<GLsizei>(log.size()), &length, log.data());
    glDeleteProgram(program);
    throw Error(Format("viewer: program ", name, " does not link: ", log.substr(0, length)));
  }
  return program;
}

// A buffer texture over `data` with internal format `format`.
struct BufferTexture {
  GLuint buffer = 0, texture = 0;
  template <typename T>
  void Upload(const std::vector<T>& data, GLenum format) {
    static const T kOne[4] = {};
    glGenBuffers(1, &buffer);
    glBindBuffer(GL_TEXTURE_BUFFER, buffer);
    // An empty field still gets one element: sampling an empty buffer texture is undefined.
    if (data.empty()) {
      glBufferData(GL_TEXTURE_BUFFER, sizeof(kOne), kOne, GL_STATIC_DRAW);
    } else {
      glBufferData(GL_TEXTURE_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(T)), data.data(),
                   GL_STATIC_DRAW);
    }
    glGenTextures(1, &texture);
    glBindTexture(GL_TEXTURE_BUFFER, texture);
    glTexBuffer(GL_TEXTURE_BUFFER, format, buffer);
    glBindTexture(GL_TEXTURE_BUFFER, 0);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
  }
  void Release() {
    glDeleteTextures(1, &texture);
    glDeleteBuffers(1, &buffer);
  }
};

// One Mesh Colors field on the GPU: faces, lattice, colours, labels (shaders.h).
struct FieldGpu {
  std::array<BufferTexture, 4> tables;
  bool present = false;
  void Upload(const MeshColors* colors) {
    present = colors != nullptr;
    const MeshColorsTables t = colors ? BuildMeshColorsTables(*colors) : MeshColorsTables();
    tables[0].Upload(t.face_table, GL_RG32I);
    tables[1].Upload(t.lattice_index, GL_R32I);
    tables[2].Upload(t.rgba, GL_RGBA32F);
    tables[3].Upload(t.labels, GL_R32I);
  }
  void Bind(int first_unit) const {
    for (int k = 0; k < 4; ++k) {
      glActiveTexture(GL_TEXTURE0 + first_unit + k);
      glBindTexture(GL_TEXTURE_BUFFER, tables[k].texture);
    }
  }
  void Release() {
    for (BufferTexture& t : tables) t.Release();
  }
};

// A vertex array of interleaved floats: xyz, or xyz rgb when `with_color`.
struct VertexArray {
  GLuint vao = 0, vbo = 0;
  GLsizei count = 0;
  void Upload(const std::vector<float>& data, bool with_color) {
    if (!vao) {
      glGenVertexArrays(1, &vao);
      glGenBuffers(1, &vbo);
    }
    const int stride = with_color ? 6 : 3;
    count = static_cast<GLsizei>(data.size() / stride);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data(),
                 GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride * sizeof(float), nullptr);
    if (with_color) {
      glEnableVertexAttribArray(1);
      glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride * sizeof(float),
                            reinterpret_cast<const void*>(3 * sizeof(float)));
    }
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
  }
  void Draw(GLenum primitive) const {
    if (count == 0) return;
    glBindVertexArray(vao);
    glDrawArrays(primitive, 0, count);
    glBindVertexArray(0);
  }
  void Release() {
    glDeleteBuffers(1, &vbo);
    glDeleteVertexArrays(1, &vao);
  }
};

void SetMatrix(GLuint program, const char* name, const Eigen::Matrix4f& m) {
  glUniformMatrix4fv(glGetUniformLocation(program, name), 1, GL_FALSE, m.data());  // column-major
}

}  // namespace

struct Renderer::Impl {
  GLuint mesh_program = 0, overlay_program = 0;
  VertexArray mesh, refined, lines, triangles;
  FieldGpu observed, albedo;
  Overlay base_overlay;  // trajectory and frusta; lights are added by SetLights
  Eigen::AlignedBox3d bounds;
  Eigen::AlignedBox3d base_bounds;

  void UploadOverlay(const std::vector<LightGlyph>& lights) {
    Overlay overlay = base_overlay;
    const double size = base_bounds.isEmpty() ? 1.0 : base_bounds.diagonal().norm();
    AddLightGlyphs(lights, 0.012 * size, &overlay);
    lines.Upload(overlay.lines, true);
    triangles.Upload(overlay.triangles, true);
    bounds = base_bounds;
    for (const LightGlyph& l : lights) bounds.extend(l.position);
  }
};

Renderer::Renderer(const ViewData& data) : impl_(std::make_unique<Impl>()) {
  const int version = epoxy_gl_version();
  if (version < 33) {
    throw Error(Format("viewer: OpenGL ", version / 10, ".", version % 10,
                       " context, but the viewer needs 3.3 core"));
  }
  Impl& m = *impl_;
  m.mesh_program = LinkProgram(shaders::kMeshVertex, shaders::kMeshFragment, "mesh");
  m.overlay_program = LinkProgram(shaders::kOverlayVertex, shaders::kOverlayFragment, "overlay");
  glUseProgram(m.mesh_program);
  const char* samplers[8] = {"faces0", "lattice0", "colors0", "labels0",
                             "faces1", "lattice1", "colors1", "labels1"};
  for (int k = 0; k < 8; ++k) glUniform1i(glGetUniformLocation(m.mesh_program, samplers[k]), k);
  glUseProgram(0);

  if (data.mesh) m.mesh.Upload(UnindexedPositions(*data.mesh), false);
  if (data.refined_mesh) m.refined.Upload(UnindexedPositions(*data.refined_mesh), false);
  m.observed.Upload(data.observed ? &*data.observed : nullptr);
  m.albedo.Upload(data.albedo ? &*data.albedo : nullptr);

  m.base_bounds = SceneBounds(data);
  const double scene_size = m.base_bounds.isEmpty() ? 1.0 : m.base_bounds.diagonal().norm();
  AddTrajectory(data.trajectory, &m.base_overlay);
  AddFrusta(data.keyframes, std::max(0.04 * scene_size, 1e-3), &m.base_overlay);
  if (data.distant) AddDistantGlyph(*data.distant, m.base_bounds, &m.base_overlay);
  m.UploadOverlay(data.lights);
}

Renderer::~Renderer() {
  Impl& m = *impl_;
  m.mesh.Release();
  m.refined.Release();
  m.lines.Release();
  m.triangles.Release();
  m.observed.Release();
  m.albedo.Release();
  glDeleteProgram(m.mesh_program);
  glDeleteProgram(m.overlay_program);
}

bool Renderer::Supports(ColorMode mode) const {
  const Impl& m = *impl_;
  if (m.mesh.count == 0) return false;
  switch (mode) {
    case ColorMode::kObserved:
      return m.observed.present;
    case ColorMode::kAlbedo:
    case ColorMode::kClusters:
      return m.albedo.present;
    case ColorMode::kShading:
      return m.observed.present && m.albedo.present;
    case ColorMode::kGeometry:
      return true;
  }
  return false;
}

bool Renderer::HasRefinedMesh() const {
  return impl_->refined.count > 0;
}

void Renderer::SetLights(const std::vector<LightGlyph>& lights) {
  impl_->UploadOverlay(lights);
}

Eigen::AlignedBox3d Renderer::Bounds() const {
  return impl_->bounds;
}

void Renderer::Draw(const PosedView& view, const DrawOptions& options) {
  Impl& m = *impl_;
  glViewport(0, 0, view.intrinsics.width, view.intrinsics.height);
  glClearColor(options.background.x(), options.background.y(), options.background.z(), 1.0f);
  if (options.encode_srgb) {
    glClearColor(LinearToSrgb(options.background.x()), LinearToSrgb(options.background.y()),
                 LinearToSrgb(options.background.z()), 1.0f);
  }
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  if (options.cull_back_faces) {
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
  } else {
    glDisable(GL_CULL_FACE);
  }
  const Eigen::Vector3d eye = view.world_from_camera.translation();
  const Eigen::Matrix4f clip_from_world = ClipFromWorld(view, ClipRangeFor(m.bounds, eye));

  // The mesh, Mesh Colors per fragment.
  const bool supported = Supports(options.mode);
  const VertexArray& mesh = options.show_refined && m.refined.count > 0 ? m.refined : m.mesh;
  glUseProgram(m.mesh_program);
  SetMatrix(m.mesh_program, "clip_from_world", clip_from_world);
  glUniform1i(glGetUniformLocation(m.mesh_program, "mode"),
              supported ? static_cast<int>(options.mode) : static_cast<int>(ColorMode::kGeometry));
  glUniform1i(glGetUniformLocation(m.mesh_program, "linear_lookup"),
              options.lookup == Lookup::kLinear);
  glUniform1i(glGetUniformLocation(m.mesh_program, "encode_srgb"), options.encode_srgb);
  glUniform3f(glGetUniformLocation(m.mesh_program, "eye"), static_cast<float>(eye.x()),
              static_cast<float>(eye.y()), static_cast<float>(eye.z()));
  m.observed.Bind(0);
  m.albedo.Bind(4);
  mesh.Draw(GL_TRIANGLES);

  // The overlay: trajectory, frusta, light glyphs.
  if (options.show_overlay) {
    glDisable(GL_CULL_FACE);
    glUseProgram(m.overlay_program);
    SetMatrix(m.overlay_program, "clip_from_world", clip_from_world);
    glUniform1i(glGetUniformLocation(m.overlay_program, "encode_srgb"), options.encode_srgb);
    m.triangles.Draw(GL_TRIANGLES);
    m.lines.Draw(GL_LINES);
  }
  glUseProgram(0);
}

ImageRgb Renderer::RenderImage(const PosedView& view, const DrawOptions& options) {
  const int w = view.intrinsics.width, h = view.intrinsics.height;
  GLuint fbo = 0, color = 0, depth = 0;
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glGenRenderbuffers(1, &color);
  glBindRenderbuffer(GL_RENDERBUFFER, color);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA32F, w, h);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
  glGenRenderbuffers(1, &depth);
  glBindRenderbuffer(GL_RENDERBUFFER, depth);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  ImageRgb image;
  if (status == GL_FRAMEBUFFER_COMPLETE) {
    DrawOptions linear = options;
    linear.encode_srgb = false;
    Draw(view, linear);
    std::vector<float> rows(static_cast<size_t>(w) * h * 3);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, w, h, GL_RGB, GL_FLOAT, rows.data());
    // glReadPixels returns the bottom row first.
    image = ImageRgb(w, h);
    for (int v = 0; v < h; ++v) {
      const float* row = rows.data() + static_cast<size_t>(h - 1 - v) * w * 3;
      for (int u = 0; u < w; ++u)
        image(u, v) = Eigen::Vector3f(row[3 * u], row[3 * u + 1], row[3 * u + 2]);
    }
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glDeleteRenderbuffers(1, &depth);
  glDeleteRenderbuffers(1, &color);
  glDeleteFramebuffers(1, &fbo);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw Error(Format("viewer: offscreen framebuffer ", w, "x", h, " incomplete (status 0x",
                       std::hex, status, ")"));
  }
  return image;
}

}  // namespace genscene::viewer
