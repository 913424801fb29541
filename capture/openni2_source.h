// Frame sources on OpenNI2: a live camera (`openni2` = the first device,
// `openni2:URI` = that device) or a .oni recording, which OpenNI2 opens as a device too. Both give
// depth + colour as RgbdFrame through the FrameSource interface of core/frame_source.h, so fusion
// reads them unchanged. Only this file and its .cpp see OpenNI2 types.
//
// The traps of Debian's OpenNI2 (DESIGN.md §5) and how they are avoided here:
// - no camera: enumerateDevices finds nothing -> one clear error line, never a hang;
// - PlaybackControl::seek crashes -> never called; recordings are stepped frame by frame with
//   setSpeed(-1) (manual) and repeat off;
// - readFrame blocks forever at the end of a recording -> frames are counted against
//   getNumberOfFrames, and every wait is waitForAnyStream with a timeout;
// - a stream without xnCropping plays no frames -> the file is inspected first (oni_format.h) and
//   such files are refused with a clear message.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/frame_source.h"

namespace genscene::capture {

// The one line shown when no camera is attached.
inline constexpr const char* kNoDeviceMessage =
    "no OpenNI2 device found \xE2\x80\x94 connect a camera or give a .oni file or a folder";

struct CaptureOptions {
  static constexpr const char* kSection = "capture";

  // Stream mode of a live camera (recordings keep their own): 640x480 or 320x240.
  std::string mode = "640x480";
  int fps = 30;  // frames per second of a live camera
  // Longest wait for the next frame, seconds: a live camera's stream then ends (with the frames
  // received), a recording is reported as damaged.
  double frame_timeout = 2.0;
  // Register depth to colour and synchronise the two streams when the device supports it.
  bool registration = true;

  template <typename V>
  void Visit(V&& v) {
    v("mode", mode, "", "live camera stream size: 640x480 or 320x240");
    v("fps", fps, "Hz", "live camera frame rate (30)");
    v("frame_timeout", frame_timeout, "s",
      "longest wait for the next frame: a live stream then ends with the frames received");
    v("registration", registration, "",
      "register depth to colour and sync frames when the device can");
  }
  void Validate() const;
  int Width() const;   // from mode
  int Height() const;  // from mode
};

// URIs of the attached OpenNI2 cameras (recordings opened in this process are left out).
std::vector<std::string> ListCameraUris();

// True for the specifications OpenOpenNI2Source takes: "openni2", "openni2:URI", "*.oni".
bool IsOpenNI2Spec(const std::string& spec);
// True for a live camera: "openni2" or "openni2:URI".
bool IsLiveCameraSpec(const std::string& spec);

// Opens a live OpenNI2 camera or a .oni recording. Intrinsics: options.intrinsics when given,
// else the exact ones genscene stored in the recording, else the device's field of view with the
// principal point at the image centre. Colour is converted to linear with
// options.camera_response; depth from millimetres to meters. first_frame / stride / max_frames
// apply. Throws Error with kNoDeviceMessage when no camera is attached, and a clear message for
// files that are not playable .oni recordings.
std::unique_ptr<FrameSource> OpenOpenNI2Source(const std::string& spec,
                                               const SourceOptions& options,
                                               const CaptureOptions& capture = CaptureOptions());

// Any source: .oni recordings and OpenNI2 cameras here, folders (TUM, Redwood, view sets) through
// core's OpenFrameSource. The capture stage reads every kind of input (DESIGN.md §2), so the
// dispatch lives here and apps call only this.
std::unique_ptr<FrameSource> OpenAnySource(const std::string& spec, const SourceOptions& options,
                                           const CaptureOptions& capture = CaptureOptions());

}  // namespace genscene::capture
