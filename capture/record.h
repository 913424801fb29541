// Recording: frames from any source (a live camera, a .oni file, a TUM folder ...) written as a
// .oni recording (oni_format.h) and/or a TUM folder (core/sequence_writer.h). Both outputs are
// atomic: a failed or interrupted run leaves no half-written file behind.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "core/color.h"
#include "core/frame_source.h"

namespace genscene::capture {

struct RecordTargets {
  std::filesystem::path oni;  // empty: no .oni output
  std::filesystem::path
      tum_folder;  // empty: no TUM folder (frames are held in memory until the end)
};

struct RecordSettings {
  size_t max_frames = 0;  // 0 = until the source ends (or `stop` is set)
  int fps = 30;           // frame rate stored in the .oni file
  bool mirror = false;  // write the .oni mirrored (xnMirror = 1, frames flipped), as NiViewer does
  CameraResponse response;  // how 8-bit colour encodes linear values (the source's response)
  // Set from another thread or a signal handler to end a live recording after the current frame.
  const std::atomic<bool>* stop = nullptr;
  // Called after each frame with (frames so far, expected total if known).
  std::function<void(size_t, std::optional<size_t>)> progress;
};

struct RecordSummary {
  size_t frames = 0;
  double first_timestamp = 0.0, last_timestamp = 0.0;  // seconds
  size_t skipped = 0;  // live camera frames the recording missed (FrameSource::SkippedFrames)
};

// Reads frames from `source` and writes them to the targets. Throws Error when there is no target,
// the source gives no frame, or a frame does not fit the .oni container (depth beyond 65.535 m).
RecordSummary RecordFrames(FrameSource& source, const RecordTargets& targets,
                           const RecordSettings& settings);

}  // namespace genscene::capture
