// Mesh Colors (.mcol) through core/mesh_colors, read onto a fixed mesh (two triangles).
#include "core/mesh_colors.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

namespace {

const TriangleMesh& Quad() {
  static const TriangleMesh mesh = [] {
    TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    m.faces = {{0, 1, 2}, {0, 2, 3}};
    return m;
  }();
  return mesh;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    WriteMeshColors(dir / "r1.mcol", MeshColors(Quad(), {1, 1}));
    WriteMeshColors(dir / "r4.mcol", MeshColors(Quad(), {4, 2}));
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.mcol", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadMeshColors(path, Quad()));
  return 0;
}
