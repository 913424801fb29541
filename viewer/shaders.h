// GLSL 3.30 sources of the viewer. The fragment shader evaluates Mesh Colors exactly as
// core/mesh_colors.cpp does (MeshColors::Locate, Nearest, Linear), from the fragment's
// barycentric coordinates and gl_PrimitiveID (= the face index: faces are drawn unindexed, in
// order, in one call).
#pragma once

namespace genscene::viewer::shaders {

inline constexpr const char* kMeshVertex = R"glsl(
#version 330 core
layout(location = 0) in vec3 position;
uniform mat4 clip_from_world;
out vec2 bary;        // (b1, b2): b0 = 1 - b1 - b2 belongs to the face's first vertex
out vec3 world_pos;
void main() {
  int corner = gl_VertexID % 3;
  bary = vec2(corner == 1 ? 1.0 : 0.0, corner == 2 ? 1.0 : 0.0);
  world_pos = position;
  gl_Position = clip_from_world * vec4(position, 1.0);
}
)glsl";

inline constexpr const char* kMeshFragment = R"glsl(
#version 330 core
in vec2 bary;
in vec3 world_pos;
// Field 0 = observed colour (texture.mcol), field 1 = albedo (albedo.mcol). Per field:
//   faces:   RG32I per face (first lattice entry, R)
//   lattice: R32I, global sample index of each lattice point (rows j = 0..R of R + 1 - j points)
//   colors:  RGBA32F per sample, linear RGB
//   labels:  R32I per sample
uniform isamplerBuffer faces0, lattice0, labels0;
uniform samplerBuffer colors0;
uniform isamplerBuffer faces1, lattice1, labels1;
uniform samplerBuffer colors1;
uniform int mode;            // 0 observed, 1 albedo, 2 shading, 3 clusters, 4 geometry
uniform int linear_lookup;   // 0 nearest, 1 linear
uniform int encode_srgb;
uniform vec3 eye;
out vec4 frag_color;

// The sub-triangle of the lattice holding (b1, b2), its three lattice points and weights:
// MeshColors::Locate.
void Locate(int r, vec2 b, out ivec2 p[3], out vec3 w) {
  b = vec2(b.x > 0.0 ? min(b.x, 1.0) : 0.0, b.y > 0.0 ? min(b.y, 1.0) : 0.0);
  if (b.x + b.y > 1.0) b /= (b.x + b.y);
  vec2 xy = b * float(r);
  int i = min(int(xy.x), r);
  int j = min(int(xy.y), r);
  while (i + j > r - 1) {
    if (i >= j && i > 0) --i; else --j;
  }
  vec2 f = xy - vec2(i, j);
  if (f.x + f.y > 1.0 && i + j < r - 1) {
    p[0] = ivec2(i + 1, j + 1); p[1] = ivec2(i, j + 1); p[2] = ivec2(i + 1, j);
    w = vec3(f.x + f.y - 1.0, max(0.0, 1.0 - f.x), max(0.0, 1.0 - f.y));
  } else {
    if (f.x + f.y > 1.0) f /= (f.x + f.y);
    p[0] = ivec2(i, j); p[1] = ivec2(i + 1, j); p[2] = ivec2(i, j + 1);
    w = vec3(max(0.0, 1.0 - f.x - f.y), f.x, f.y);
  }
}

int SampleIndex(isamplerBuffer faces, isamplerBuffer lattice, int face, ivec2 p) {
  ivec2 fr = texelFetch(faces, face).xy;
  int local = p.y * (fr.y + 1) - p.y * (p.y - 1) / 2 + p.x;
  return texelFetch(lattice, fr.x + local).x;
}

// Index of the sample Nearest picks, and the three samples with weights for Linear.
void Lookup(isamplerBuffer faces, isamplerBuffer lattice, int face, vec2 b, out ivec3 idx, out vec3 w) {
  int r = texelFetch(faces, face).y;
  ivec2 p[3];
  Locate(r, b, p, w);
  for (int k = 0; k < 3; ++k) idx[k] = SampleIndex(faces, lattice, face, p[k]);
}

int NearestOf(vec3 w) {
  int best = 0;
  if (w.y > w[best]) best = 1;
  if (w.z > w[best]) best = 2;
  return best;
}

vec3 Field(isamplerBuffer faces, isamplerBuffer lattice, samplerBuffer colors, int face, vec2 b) {
  ivec3 idx; vec3 w;
  Lookup(faces, lattice, face, b, idx, w);
  if (linear_lookup == 0) return texelFetch(colors, idx[NearestOf(w)]).rgb;
  return w.x * texelFetch(colors, idx.x).rgb + w.y * texelFetch(colors, idx.y).rgb +
         w.z * texelFetch(colors, idx.z).rgb;
}

vec3 FalseColor(int label) {
  if (label < 0) return vec3(0.0);
  uint h = uint(label) * 2654435761u;
  h ^= h >> 15u; h *= 2246822519u; h ^= h >> 13u;
  return 0.15 + 0.85 * vec3(float(h & 255u), float((h >> 8u) & 255u), float((h >> 16u) & 255u)) / 255.0;
}

float Srgb(float c) {
  c = clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

void main() {
  int face = gl_PrimitiveID;
  vec3 c;
  if (mode == 0) {
    c = Field(faces0, lattice0, colors0, face, bary);
  } else if (mode == 1) {
    c = Field(faces1, lattice1, colors1, face, bary);
  } else if (mode == 2) {
    vec3 observed = Field(faces0, lattice0, colors0, face, bary);
    vec3 albedo = Field(faces1, lattice1, colors1, face, bary);
    c = observed / max(albedo, vec3(1e-3));
  } else if (mode == 3) {
    ivec3 idx; vec3 w;
    Lookup(faces1, lattice1, face, bary, idx, w);
    c = FalseColor(texelFetch(labels1, idx[NearestOf(w)]).x);
  } else {
    vec3 n = normalize(cross(dFdx(world_pos), dFdy(world_pos)));
    float lit = abs(dot(n, normalize(eye - world_pos)));
    c = vec3(0.7) * (0.2 + 0.8 * lit);
  }
  if (encode_srgb != 0) c = vec3(Srgb(c.r), Srgb(c.g), Srgb(c.b));
  frag_color = vec4(c, 1.0);
}
)glsl";

inline constexpr const char* kOverlayVertex = R"glsl(
#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 color;
uniform mat4 clip_from_world;
out vec3 vertex_color;
void main() {
  vertex_color = color;
  gl_Position = clip_from_world * vec4(position, 1.0);
}
)glsl";

inline constexpr const char* kOverlayFragment = R"glsl(
#version 330 core
in vec3 vertex_color;
uniform int encode_srgb;
out vec4 frag_color;
float Srgb(float c) {
  c = clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}
void main() {
  vec3 c = vertex_color;
  if (encode_srgb != 0) c = vec3(Srgb(c.r), Srgb(c.g), Srgb(c.b));
  frag_color = vec4(c, 1.0);
}
)glsl";

}  // namespace genscene::viewer::shaders
