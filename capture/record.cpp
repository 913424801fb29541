#include "capture/record.h"

#include <memory>
#include <vector>

#include "capture/oni_format.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/sequence_writer.h"

namespace genscene::capture {

namespace fs = std::filesystem;

RecordSummary RecordFrames(FrameSource& source, const RecordTargets& targets,
                           const RecordSettings& settings) {
  if (targets.oni.empty() && targets.tum_folder.empty()) {
    throw Error("nothing to record to: give a .oni file and/or a TUM folder");
  }
  RecordSummary summary;
  std::vector<RgbdFrame> kept;  // for the TUM folder, written at the end
  std::optional<size_t> expected = source.FrameCount();
  if (settings.max_frames > 0)
    expected = std::min(expected.value_or(settings.max_frames), settings.max_frames);

  // One loop for both targets; the .oni writer (when there is one) streams to its temporary file.
  const auto read_frames = [&](OniWriter* oni) {
    while (settings.max_frames == 0 || summary.frames < settings.max_frames) {
      if (settings.stop && settings.stop->load()) break;
      std::optional<RgbdFrame> frame = source.Next();
      if (!frame) break;
      if (oni) oni->Add(ToOniRawFrame(*frame, settings.response));
      if (summary.frames == 0) summary.first_timestamp = frame->timestamp;
      summary.last_timestamp = frame->timestamp;
      ++summary.frames;
      if (!targets.tum_folder.empty()) kept.push_back(std::move(*frame));
      if (settings.progress) settings.progress(summary.frames, expected);
    }
    if (summary.frames == 0) throw Error(Format(source.Describe(), ": no frames to record"));
    summary.skipped = source.SkippedFrames();
  };

  if (!targets.oni.empty()) {
    OniLayout layout;
    layout.intrinsics = source.Intrinsics();
    layout.width = layout.intrinsics.width;
    layout.height = layout.intrinsics.height;
    layout.fps = settings.fps;
    layout.mirrored = settings.mirror;
    WriteFileAtomically(targets.oni, [&](const fs::path& tmp) {
      OniWriter writer(tmp, layout);
      read_frames(&writer);
      writer.Finish();
    });
  } else {
    read_frames(nullptr);
  }
  if (!targets.tum_folder.empty()) {
    TumWriteOptions tum;
    tum.response = settings.response;
    WriteTumSequence(targets.tum_folder, kept, tum);
  }
  return summary;
}

}  // namespace genscene::capture
