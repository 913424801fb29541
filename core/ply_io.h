// PLY mesh I/O (a reader and a writer of our own, core/ply_io.cpp), readable by MeshLab, Open3D
// and Blender. Binary little-endian by default.
//
// Colour convention on disk: `red/green/blue` uchar properties are sRGB-encoded 8-bit (what
// MeshLab and Open3D display) and are converted to/from linear on read/write; float vertex and
// face properties are linear (DESIGN.md §2), named for what they hold: `albedo_r/g/b` the
// reflectance, `color_r/g/b` the colour a camera observed (shading included). On read the float
// properties are preferred (albedo first).
#pragma once

#include <filesystem>

#include "core/mesh.h"

namespace genscene {

// What a mesh's vertex and face colours are, which names the float colour properties.
enum class PlyColors {
  kAlbedo,    // albedo_r/g/b: reflectance (the albedo stage, the exported model)
  kObserved,  // color_r/g/b: observed colour, shading included (fusion, the texture)
};

struct PlyWriteOptions {
  bool binary = true;  // false: ASCII
  PlyColors colors = PlyColors::kAlbedo;
};

// Reads ASCII or binary little-endian PLY: positions, faces (polygons are fan-triangulated), and
// when present vertex normals, vertex colours and face colours/albedo. Vertices and faces are
// exactly those of the file, in file order (a non-manifold mesh reads as it is). The header is
// checked against the file size before anything is allocated, so a truncated file or a header
// claiming 10^9 vertices is an Error naming the file, not an allocation. Throws Error naming the
// file and the problem on any problem (e.g. a truncated file, a value that is not a number, a
// face index out of range, a face with fewer than 3 corners, big-endian data).
TriangleMesh ReadPly(const std::filesystem::path& path);

// Writes the mesh atomically: positions, faces, and normals / vertex colours / face colours when
// non-empty (vertex and face colours as exact float albedo_r/g/b or color_r/g/b, as
// options.colors says, and as uchar red/green/blue sRGB, clamped to [0, 1], for viewers).
void WritePly(const std::filesystem::path& path, const TriangleMesh& mesh,
              const PlyWriteOptions& options = PlyWriteOptions());

}  // namespace genscene
