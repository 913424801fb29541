// PLY meshes (ASCII and binary, with normals and colours) through core/ply_io.
#include "core/file_util.h"
#include "core/ply_io.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

namespace {

TriangleMesh Tetrahedron() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    TriangleMesh m = Tetrahedron();
    WritePly(dir / "plain.ply", m);
    m.normals.assign(4, Eigen::Vector3f(0, 0, 1));
    m.vertex_colors.assign(4, Eigen::Vector3f(0.5f, 0.25f, 1.0f));
    m.face_colors.assign(4, Eigen::Vector3f(0.1f, 0.2f, 0.3f));
    WritePly(dir / "coloured.ply", m);
    WriteTextFileAtomically(
        dir / "ascii.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.ply", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadPly(path));
  return 0;
}
