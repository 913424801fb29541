// libFuzzer harnesses for every parser. Each harness writes its input to a scratch
// file, whose extension chooses the format, and calls one reader. genscene::Error is the expected
// answer to bad input; anything else is a finding: another exception (uncaught: std::terminate),
// a crash, an ASan / UBSan report, a hang (-timeout) or an allocation over -malloc_limit_mb.
//
// Seeds: run a harness with GENSCENE_FUZZ_SEEDS=DIR and it writes valid inputs made by our own
// writers into DIR and exits; scripts/fuzz.sh adds files of ../shared/data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "core/check.h"

namespace genscene::fuzz {

// A scratch folder of this process (under $GENSCENE_FUZZ_TMPDIR, else /dev/shm, else /tmp;
// removed at exit).
const std::filesystem::path& ScratchDir();

// `data` written to ScratchDir() / name.
std::filesystem::path Scratch(const std::string& name, const uint8_t* data, size_t size);

// When GENSCENE_FUZZ_SEEDS names a folder, calls write(folder) and exits the process.
void MaybeWriteSeeds(const std::function<void(const std::filesystem::path&)>& write);

}  // namespace genscene::fuzz

// Runs `body`; a genscene::Error (the readers' clear error) is the expected outcome of bad input.
#define GENSCENE_FUZZ_EXPECT_ERROR_OK(...) \
  do {                                     \
    try {                                  \
      __VA_ARGS__;                         \
    } catch (const genscene::Error&) {     \
    }                                      \
  } while (0)
