// Wavefront OBJ through render/formats/mesh_sources (ReadObj).
#include "core/file_util.h"
#include "fuzz/fuzz_util.h"
#include "render/formats/mesh_sources.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    WriteTextFileAtomically(
        dir / "quad.obj",
        "# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 4//1\nf -4 -2 -1\n");
    WriteTextFileAtomically(dir / "poly.obj",
                            "o p\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng a\ns 1\nf 1 2 3 4\n");
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.obj", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(render::ReadObj(path));
  return 0;
}
