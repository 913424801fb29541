// Config files (JSON, one object per section) through core/options: ConfigFile, Apply into the
// options of the input, the renderer, light estimation and refinement (every value type), and the
// unknown-key check. (The options' own Validate() range checks live in the stage libraries, which
// the fuzz build does not compile.)
#include "core/file_util.h"
#include "core/frame_source.h"
#include "core/options.h"
#include "fuzz/fuzz_util.h"
#include "inverse/lights/light_estimation.h"
#include "inverse/refine/vertex_refinement.h"
#include "render/path_tracer.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    WriteTextFileAtomically(dir / "config.json",
                            "{\"source\": {\"depth_scale\": 5000, \"intrinsics\": \"tum1\"},\n"
                            " \"lights\": {\"grid\": 5, \"spp\": 8, \"penalty_weight\": 1e-4},\n"
                            " \"refine\": {\"iterations\": 3},\n \"render\": {\"spp\": 4},\n"
                            " \"fusion\": {\"voxel_size\": 0.01}}\n");
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("config.json", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK({
    ConfigFile config(path);
    SourceOptions source;
    inverse::LightEstimationOptions lights;
    inverse::RefineOptions refine;
    render::RenderOptions render;
    config.Apply(source);
    config.Apply(lights);
    config.Apply(refine);
    config.Apply(render);
    config.CheckNoUnknown(AllConfigSections());
  });
  return 0;
}
