// genscene-capture: record RGB-D frames from an OpenNI2 camera (or convert any frame source) into
// a .oni recording and/or a TUM folder.
//
//   genscene-capture --record room.oni --max-frames 300      live camera -> .oni
//   genscene-capture --out room_tum --max-frames 300         live camera -> TUM folder
//   genscene-capture --input data/tum --record data.oni      TUM folder -> .oni (no camera needed)
//   genscene-capture --input room.oni --out room_tum         .oni -> TUM folder
#include <atomic>
#include <csignal>
#include <iostream>

#include "capture/openni2_source.h"
#include "capture/record.h"
#include "core/cli.h"

namespace {

std::atomic<bool> g_stop{false};
void OnInterrupt(int) {
  g_stop = true;
}

}  // namespace

int main(int argc, char** argv) {
  return genscene::RunApp("genscene-capture", [&] {
    CLI::App app{
        "genscene-capture: record depth + colour frames from an OpenNI2 camera, or convert any "
        "frame "
        "source, into a .oni recording (--record) and/or a TUM folder (--out). Both are written "
        "atomically: an interrupted or failed run leaves no partial output."};
    genscene::CommandLine cli(app);
    genscene::SourceOptions source;
    genscene::capture::CaptureOptions camera;
    cli.Add(source, "Input");
    cli.Add(camera, "Camera");
    std::string input = "openni2", out, record;
    int file_fps = 30;
    app.add_option("--input", input,
                   "openni2 (first camera), openni2:URI, a .oni recording, or a TUM / Redwood "
                   "folder or view set")
        ->capture_default_str();
    cli.AddFolder(out, "workspace",
                  "write the frames as a TUM folder (rgb/, depth/, rgb.txt, depth.txt, "
                  "intrinsics.txt); frames are held in memory until the end",
                  false);
    app.add_option("--record", record,
                   "write the frames as an uncompressed .oni recording (OpenNI2 plays it)");
    app.add_option("--record-fps", file_fps, "frame rate stored in the .oni file")
        ->capture_default_str();
    bool mirror = false;
    app.add_flag(
        "--record-mirrored", mirror,
        "write the .oni as a camera with mirroring on records it (xnMirror = 1, every frame "
        "flipped "
        "left-right, as NiViewer's recordings); genscene reads either kind the right way round");
    if (auto code = cli.Parse(argc, argv)) return *code;

    if (out.empty() && record.empty()) {
      throw genscene::Error(
          "nothing to do: give --record FILE.oni and/or --out FOLDER (a TUM folder)");
    }
    if (!record.empty() && !genscene::capture::IsOpenNI2Spec(record)) {
      throw genscene::Error(
          genscene::Format("--record ", record, ": the file name must end in .oni"));
    }
    auto frame_source = genscene::capture::OpenAnySource(input, source, camera);
    std::cerr << "capturing from " << frame_source->Describe() << "\n";
    // Ctrl-C ends a live recording cleanly: the frames so far are written, complete; so does a
    // camera that is unplugged or stalls (with a warning). (A file or folder being converted is
    // stopped by Ctrl-C as usual, leaving no output.)
    if (!frame_source->FrameCount()) std::signal(SIGINT, OnInterrupt);

    genscene::capture::RecordSettings settings;
    settings.max_frames = static_cast<size_t>(source.max_frames);  // the source stops there too
    settings.fps = file_fps;
    settings.mirror = mirror;
    settings.response = genscene::CameraResponse::Parse(source.camera_response);
    settings.stop = &g_stop;
    settings.progress = [](size_t n, std::optional<size_t> total) {
      std::cerr << "\rcapturing: " << n;
      if (total) std::cerr << "/" << *total;
      std::cerr << " frames" << std::flush;
    };
    const auto summary = genscene::capture::RecordFrames(*frame_source, {record, out}, settings);
    std::cerr << "\n";
    std::cout << "source:  " << frame_source->Describe() << "\n"
              << "frames:  " << summary.frames << " (t = " << std::fixed << summary.first_timestamp
              << " .. " << summary.last_timestamp << " s)" << std::defaultfloat << "\n"
              << "wrote:   " << record << (record.empty() || out.empty() ? "" : ", ") << out
              << "\n";
    if (!frame_source->FrameCount()) {
      std::cout << "skipped: " << summary.skipped
                << " camera frames (dropped by the camera or missed while writing)\n";
    }
    return 0;
  });
}
