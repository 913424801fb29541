#include "capture/openni2_source.h"

#include <OpenNI.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>
#include <utility>

#include "capture/oni_format.h"
#include "core/check.h"
#include "core/color.h"
#include "core/options.h"

namespace genscene::capture {

namespace fs = std::filesystem;

void CaptureOptions::Validate() const {
  RequireOneOf("mode", mode, {"640x480", "320x240"});
  RequireRange("fps", fps, 1, 120);
  RequireRange("frame_timeout", frame_timeout, 0.05, 600.0);
}

int CaptureOptions::Width() const {
  return mode == "320x240" ? 320 : 640;
}
int CaptureOptions::Height() const {
  return mode == "320x240" ? 240 : 480;
}

bool IsLiveCameraSpec(const std::string& spec) {
  return spec == "openni2" || spec.rfind("openni2:", 0) == 0;
}

bool IsOpenNI2Spec(const std::string& spec) {
  if (IsLiveCameraSpec(spec)) return true;
  std::string ext = fs::path(spec).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".oni";
}

namespace {

// OpenNI2 is initialised once per process (it loads its drivers from
// <libdir>/OpenNI2/Drivers, Debian: /usr/lib/x86_64-linux-gnu/OpenNI2/Drivers) and never shut
// down: shutting down while a recording's player thread winds down has no benefit at exit.
void InitializeOpenNI2() {
  static std::once_flag once;
  static openni::Status status = openni::STATUS_OK;
  static std::string error;
  std::call_once(once, [] {
    status = openni::OpenNI::initialize();
    if (status != openni::STATUS_OK) error = openni::OpenNI::getExtendedError();
  });
  if (status != openni::STATUS_OK) throw Error(Format("OpenNI2 failed to initialise: ", error));
}

std::string LastOpenNI2Error() {
  std::string e = openni::OpenNI::getExtendedError();
  while (!e.empty() && (e.back() == '\n' || e.back() == ' ')) e.pop_back();
  while (!e.empty() && (e.front() == '\t' || e.front() == ' ')) e.erase(e.begin());
  return e.empty() ? "no details" : e;
}

}  // namespace

std::vector<std::string> ListCameraUris() {
  InitializeOpenNI2();
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  std::vector<std::string> uris;
  for (int i = 0; i < devices.getSize(); ++i) {
    std::error_code ec;
    const std::string uri = devices[i].getUri();
    if (std::string(devices[i].getName()) == "oni File" || fs::is_regular_file(uri, ec)) continue;
    uris.push_back(uri);
  }
  return uris;
}

namespace {

// 8-bit code value -> linear, for one camera response. The code value is scaled as core's image
// reader (OpenCV convertTo) scales it, so both give bit-identical colours.
std::array<float, 256> LinearTable(const CameraResponse& response) {
  std::array<float, 256> table;
  for (int i = 0; i < 256; ++i)
    table[i] = response.ToLinear(static_cast<float>(i) * static_cast<float>(1.0 / 255.0));
  return table;
}

// Waits for OpenNI2's end-of-file event of one recording. The OniFile driver raises it on its
// player thread (PlayerDevice::OnEndOfFileReached, reached from the player's ReadNext once the
// end record is read), so the event also says that the player has returned from delivering the
// last frame.
class EndOfFileListener : public openni::OpenNI::DeviceStateChangedListener {
 public:
  explicit EndOfFileListener(std::string uri) : uri_(std::move(uri)) {}

  void onDeviceStateChanged(const openni::DeviceInfo* info, openni::DeviceState state) override {
    if (state != openni::DEVICE_STATE_EOF || info == nullptr || uri_ != info->getUri()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      eof_ = true;
    }
    reached_.notify_all();
  }

  // True once the event came, false after `timeout` without it.
  bool Wait(std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    return reached_.wait_for(lock, timeout, [this] { return eof_; });
  }

 private:
  const std::string uri_;
  std::mutex mutex_;
  std::condition_variable reached_;
  bool eof_ = false;
};

// Whether an opened camera is still attached: OpenNI2 drops a device from its list when the driver
// reports it disconnected (unplugged). Asked only after a wait for frames came back empty, so no
// listener has to be registered (and outlive OpenNI2's callbacks) for it.
bool StillAttached(const std::string& uri) {
  const std::vector<std::string> cameras = ListCameraUris();
  return std::find(cameras.begin(), cameras.end(), uri) != cameras.end();
}

class OpenNI2Source : public FrameSource {
 public:
  OpenNI2Source(const std::string& spec, const SourceOptions& options,
                const CaptureOptions& capture)
      : spec_(spec),
        options_(options),
        capture_(capture),
        to_linear_(LinearTable(CameraResponse::Parse(options.camera_response))) {
    InitializeOpenNI2();
    is_file_ = !IsLiveCameraSpec(spec);
    try {
      Open();
    } catch (...) {
      Close();  // the members' own destructors would tear down in the unsafe order (see Close)
      throw;
    }
  }

  ~OpenNI2Source() override { Close(); }

  std::string Describe() const override {
    return Format(is_file_ ? "OpenNI2 recording " : "OpenNI2 camera ", spec_, " (",
                  is_file_ ? Format(total_, " frames, ") : std::string(), width_, "x", height_,
                  ")");
  }
  std::optional<size_t> FrameCount() const override {
    if (!is_file_) return std::nullopt;
    size_t n = 0;
    for (int i = options_.first_frame; i < total_; i += options_.stride) ++n;
    if (options_.max_frames > 0) n = std::min<size_t>(n, options_.max_frames);
    return n;
  }
  const CameraIntrinsics& Intrinsics() const override { return intrinsics_; }
  const Trajectory& KnownPoses() const override { return no_poses_; }
  size_t SkippedFrames() const override { return skipped_; }

  std::optional<RgbdFrame> Next() override {
    if (ended_) return std::nullopt;
    if (options_.max_frames > 0 && emitted_ >= static_cast<size_t>(options_.max_frames))
      return std::nullopt;
    // Skip to the next selected frame (first_frame, then every stride-th).
    const size_t wanted = options_.first_frame + emitted_ * options_.stride;
    while (static_cast<size_t>(next_index_) < wanted) {
      if (!ReadPair()) return std::nullopt;
      ++next_index_;
    }
    if (!ReadPair()) return std::nullopt;
    ++next_index_;
    ++emitted_;
    return ToRgbdFrame();
  }

 private:
  // The constructor's work: opens the device, creates and starts the depth + colour streams.
  void Open() {
    std::optional<OniFileInfo> info;
    if (is_file_) {
      // Inspect the container first: truncated files, depth-only files and streams without
      // xnCropping would otherwise end in a crash, a hang or no frames inside OpenNI2.
      info = InspectOniFile(spec_);
      RequirePlayableRgbd(*info);
      // OpenNI2's player delivers a stream recorded with mirroring on as it was stored: flipped.
      mirrored_depth_ = info->FindNode(kOniNodeDepth)->mirrored;
      mirrored_color_ = info->FindNode(kOniNodeImage)->mirrored;
      OpenDevice(spec_.c_str());
      // Listening from before the first start: the event may come before Close asks for it.
      eof_listener_.emplace(device_.getDeviceInfo().getUri());
      if (openni::OpenNI::addDeviceStateChangedListener(&*eof_listener_) != openni::STATUS_OK)
        throw Error(
            Format(spec_, ": cannot listen to OpenNI2 device events: ", LastOpenNI2Error()));
      eof_listener_registered_ = true;
    } else {
      // A recording opened earlier in this process stays listed as a device (and would be what
      // ANY_DEVICE opens): only real cameras count, and the first one is opened by its URI.
      const std::vector<std::string> cameras = ListCameraUris();
      if (cameras.empty()) throw Error(kNoDeviceMessage);
      const std::string uri = spec_.size() > 8 ? spec_.substr(8) : cameras.front();
      OpenDevice(uri.c_str());
      uri_ = device_.getDeviceInfo().getUri();
    }
    CreateStreams();
    intrinsics_ = ChooseIntrinsics(info);
    intrinsics_.Validate(Describe());
    if (is_file_) {
      // Manual stepping, no repeat: every frame once, in order. (seek() is never used: it crashes.)
      openni::PlaybackControl* playback = device_.getPlaybackControl();
      if (!playback)
        throw Error(Format(spec_, ": OpenNI2 gives no playback control for this recording"));
      playback->setRepeatEnabled(false);
      playback->setSpeed(-1.0f);
      depth_total_ = playback->getNumberOfFrames(*depth_);
      color_total_ = playback->getNumberOfFrames(*color_);
      total_ = std::min(depth_total_, color_total_);
      if (total_ <= 0) throw Error(Format(spec_, ": OpenNI2 reports no frames"));
    }
    for (openni::VideoStream* s : {&*depth_, &*color_}) {
      if (s->start() != openni::STATUS_OK)
        throw Error(Format(spec_, ": cannot start a stream: ", LastOpenNI2Error()));
      any_started_ = true;
    }
  }

  // Releases everything OpenNI2 gave us; also after a partial Open.
  //
  // For a recording, no plain teardown order is safe with Debian's OpenNI2 2.2.0.33; which one is
  // depends on where the OniFile driver's player thread is (upstream
  // Source/Drivers/OniFile/PlayerDevice.cpp). Failures seen with two test processes side by side
  // on 2 CPUs (ctest -j2; the player thread gets preempted at the wrong moment), none alone:
  // - Streams destroyed, then the device closed (the usual order): the player thread's MainLoop
  //   walks the device's stream list (PlayerDevice::m_streams) WITHOUT the device lock -- every
  //   10 ms while no stream is started, in a busy loop once a recording has reached its end --
  //   while PlayerDevice::destroyStream (reached from oniStreamDestroy) unlinks and frees that
  //   list's node on our thread: SIGSEGV in MainLoop reading the freed node, while Device::close
  //   waits for the thread. 21 of 800 processes whose recording had played to its end.
  // - Device closed first: OpenNI2's core Device::close deletes its per-sensor objects and only
  //   then closes the driver device, which wakes and joins the player thread. A player stopped
  //   part-way is parked in OnNodeNewData holding the next frame and, once woken, delivers it into
  //   the deleted object: SIGSEGV in 52 of 300 processes that stop after 4 of 6 frames. And
  //   destroying a stream after its device is closed reads and writes that deleted object too
  //   (valgrind, every time).
  // So, for a recording whose player can hold no frame -- no stream ever started (it reads nothing
  // before a start) or both streams read to their last frame (it then reads the end record, closes
  // the file and delivers nothing more) -- the device is closed first, which joins the player
  // thread before the stream list is touched, and the two stream handles are then left alone for
  // the rest of the process (two idle OpenNI2 stream objects and threads per recording read).
  // A recording read to its end is closed only after OpenNI2's end-of-file event
  // (EndOfFileListener): before it, the player thread may still be returning from the delivery of
  // the last frame (it releases the frame through the per-sensor object after we have it) while
  // Device::close deletes that object -- 1 of 500 processes under the same load crashed so. The
  // wait comes before the streams are stopped: a player with no started stream never reads on to
  // the end record.
  // A recording stopped part-way is torn down streams first: the driver then unregisters its
  // streams, so the held frame goes nowhere, and the parked player thread walks the stream list
  // only under the device lock, once per 2 s wait (0 failures in 300 processes).
  // Live cameras: streams first, then the device, as OpenNI2 documents.
  void Close() {
    depth_frame_.release();
    color_frame_.release();
    const bool read_to_end =
        any_started_ && depth_read_ >= depth_total_ && color_read_ >= color_total_;
    if (is_file_ && read_to_end && eof_listener_registered_ &&
        !eof_listener_->Wait(std::chrono::milliseconds(kEndOfFileWaitMs))) {
      spdlog::warn("{}: OpenNI2 gave no end-of-file event within {} ms after the last frame", spec_,
                   kEndOfFileWaitMs);
    }
    for (std::optional<openni::VideoStream>* s : {&depth_, &color_}) {
      if (*s) (*s)->stop();
    }
    const bool player_holds_no_frame = !any_started_ || read_to_end;
    if (!(is_file_ && player_holds_no_frame)) {
      for (std::optional<openni::VideoStream>* s : {&depth_, &color_}) {
        if (*s && (*s)->isValid()) oniStreamDestroy((*s)->_getHandle());
      }
    }
    depth_.reset();  // the wrappers do not own the handles: nothing is destroyed here
    color_.reset();
    device_.close();  // joins the player thread: no event can come after this
    if (eof_listener_registered_) {
      openni::OpenNI::removeDeviceStateChangedListener(&*eof_listener_);
      eof_listener_registered_ = false;
    }
  }

  void OpenDevice(const char* uri) {
    if (device_.open(uri) != openni::STATUS_OK) {
      const std::string error = LastOpenNI2Error();
      if (!is_file_ && error.find("no devices found") != std::string::npos)
        throw Error(kNoDeviceMessage);
      throw Error(Format(spec_, ": OpenNI2 cannot open it: ", error));
    }
  }

  void CreateStreams() {
    if (!device_.hasSensor(openni::SENSOR_DEPTH) || !device_.hasSensor(openni::SENSOR_COLOR)) {
      throw Error(Format(spec_, ": the device has no ",
                         device_.hasSensor(openni::SENSOR_DEPTH) ? "colour" : "depth",
                         " sensor (genscene needs depth + colour)"));
    }
    for (auto [stream, sensor] :
         {std::pair{&depth_, ONI_SENSOR_DEPTH}, std::pair{&color_, ONI_SENSOR_COLOR}}) {
      OniStreamHandle handle = nullptr;
      if (oniDeviceCreateStream(device_._getHandle(), sensor, &handle) != ONI_STATUS_OK) {
        throw Error(
            Format(spec_, ": cannot create the depth and colour streams: ", LastOpenNI2Error()));
      }
      stream->emplace(handle);  // a wrapper that does not own the handle (see Close)
    }
    if (!is_file_) {
      SetLiveMode(*depth_, {openni::PIXEL_FORMAT_DEPTH_1_MM, openni::PIXEL_FORMAT_DEPTH_100_UM},
                  "depth");
      SetLiveMode(*color_, {openni::PIXEL_FORMAT_RGB888}, "colour");
      depth_->setMirroringEnabled(false);
      color_->setMirroringEnabled(false);
      if (capture_.registration) {
        if (device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
          if (device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) !=
              openni::STATUS_OK) {
            spdlog::warn("{}: depth-to-colour registration failed: {}", spec_, LastOpenNI2Error());
          }
        } else {
          spdlog::warn("{}: the device cannot register depth to colour; frames are unregistered",
                       spec_);
        }
        if (device_.setDepthColorSyncEnabled(true) != openni::STATUS_OK) {
          spdlog::warn("{}: the device cannot synchronise depth and colour frames", spec_);
        }
      }
    }
    const openni::VideoMode dm = depth_->getVideoMode(), cm = color_->getVideoMode();
    if (dm.getResolutionX() != cm.getResolutionX() || dm.getResolutionY() != cm.getResolutionY()) {
      throw Error(Format(spec_, ": depth ", dm.getResolutionX(), "x", dm.getResolutionY(),
                         " but colour ", cm.getResolutionX(), "x", cm.getResolutionY(),
                         " (genscene needs equal sizes)"));
    }
    width_ = dm.getResolutionX();
    height_ = dm.getResolutionY();
    if (width_ <= 0 || height_ <= 0)
      throw Error(Format(spec_, ": streams report size ", width_, "x", height_));
  }

  // Picks the camera mode of the requested size and rate with one of `formats`.
  void SetLiveMode(openni::VideoStream& stream, std::initializer_list<openni::PixelFormat> formats,
                   const char* what) {
    const openni::Array<openni::VideoMode>& modes = stream.getSensorInfo().getSupportedVideoModes();
    std::string available;
    for (openni::PixelFormat format : formats) {
      for (int i = 0; i < modes.getSize(); ++i) {
        const openni::VideoMode& m = modes[i];
        if (m.getResolutionX() == capture_.Width() && m.getResolutionY() == capture_.Height() &&
            m.getFps() == capture_.fps && m.getPixelFormat() == format) {
          if (stream.setVideoMode(m) != openni::STATUS_OK) {
            throw Error(Format(spec_, ": cannot set the ", what, " mode ", capture_.mode, " @ ",
                               capture_.fps, ": ", LastOpenNI2Error()));
          }
          return;
        }
      }
    }
    for (int i = 0; i < modes.getSize(); ++i) {
      available +=
          Format(i ? ", " : "", modes[i].getResolutionX(), "x", modes[i].getResolutionY(), "@",
                 modes[i].getFps(), " format ", static_cast<int>(modes[i].getPixelFormat()));
    }
    throw Error(Format(spec_, ": the camera has no ", what, " mode ", capture_.mode, " @ ",
                       capture_.fps, " Hz (it offers: ", available, ")"));
  }

  CameraIntrinsics ChooseIntrinsics(const std::optional<OniFileInfo>& info) const {
    if (!options_.intrinsics.empty()) {
      CameraIntrinsics k = ResolveIntrinsics(options_.intrinsics);
      if (k.width != width_ || k.height != height_) {
        throw Error(Format(spec_, ": frames ", width_, "x", height_, " but intrinsics ",
                           options_.intrinsics, " say ", k.width, "x", k.height));
      }
      return k;
    }
    if (info) {
      if (const OniNodeInfo* node = info->FindNode(kOniNodeDepth); node && node->gs_intrinsics) {
        const auto& v = *node->gs_intrinsics;
        CameraIntrinsics k;
        k.fx = v[0], k.fy = v[1], k.cx = v[2], k.cy = v[3], k.width = width_, k.height = height_;
        return k;
      }
    }
    // Registered depth lives in the colour camera: take the colour stream's field of view.
    const openni::VideoStream& s = (!is_file_ && capture_.registration) ? *color_ : *depth_;
    return IntrinsicsFromFieldOfView(s.getHorizontalFieldOfView(), s.getVerticalFieldOfView(),
                                     width_, height_);
  }

  // Reads the next depth frame and the next colour frame. False at the end of a recording, and when
  // a live camera was unplugged or stalled (EndLive).
  bool ReadPair() {
    if (ended_) return false;
    if (is_file_ && depth_read_ >= total_ && color_read_ >= total_) return false;
    depth_frame_.release();
    color_frame_.release();
    openni::VideoStream* streams[2] = {&*depth_, &*color_};
    const int timeout_ms = static_cast<int>(std::lround(capture_.frame_timeout * 1000.0));
    // A live camera's two streams may drop or delay a frame of one of them: a depth frame is paired
    // with the colour frame of its time. While the two are more than half a frame period apart,
    // the older one is replaced by its stream's next frame; after a second's worth of frames
    // without a match (a camera whose two streams keep unrelated clocks) frames are paired as they
    // arrive.
    for (int resyncs = 0;; ++resyncs) {
      if (!ReadUntilBothValid(streams, timeout_ms)) return false;
      if (is_file_ || !pair_by_time_) break;
      const int64_t apart = static_cast<int64_t>(depth_frame_.getTimestamp()) -
                            static_cast<int64_t>(color_frame_.getTimestamp());
      if (2 * std::abs(apart) * capture_.fps <= 1000000) break;
      if (resyncs >= capture_.fps) {
        spdlog::warn(
            "{}: depth and colour time stamps stay {} ms apart; frames are paired as "
            "they arrive",
            spec_, apart / 1000.0);
        pair_by_time_ = false;
        break;
      }
      (apart < 0 ? depth_frame_ : color_frame_).release();
    }
    // In a recording, frame numbers pair depth with colour; a mismatch means a damaged file.
    if (is_file_ && depth_frame_.getFrameIndex() != color_frame_.getFrameIndex()) {
      throw Error(Format(spec_, ": depth frame ", depth_frame_.getFrameIndex(),
                         " arrived with colour frame ", color_frame_.getFrameIndex(),
                         " (unpaired streams)"));
    }
    if (!is_file_) {
      // Camera frames between the first pair and this one that were never paired: dropped by the
      // camera, or replaced by newer ones while the reader was busy (OpenNI2 keeps the newest).
      const int64_t index = depth_frame_.getFrameIndex();
      if (pairs_read_ == 0) first_camera_index_ = index;
      ++pairs_read_;
      skipped_ = static_cast<size_t>(std::max<int64_t>(
          0, index - first_camera_index_ + 1 - static_cast<int64_t>(pairs_read_)));
    }
    return true;
  }

  // Ends a live camera's stream: the frames read so far are all there is.
  void EndLive(const std::string& why) {
    ended_ = true;
    spdlog::warn("{}: {} after {} frames; the capture ends with the frames received", spec_, why,
                 emitted_);
  }

  // Reads frames from the two streams until both frames are valid (in a recording a stream's newer
  // frame replaces an older one that is still unpaired; a live camera reads only the missing one).
  // False when a live camera was unplugged or gave no frame within the timeout: its stream ends
  // there (EndLive). A recording that stops delivering frames is damaged: an Error.
  bool ReadUntilBothValid(openni::VideoStream* streams[2], int timeout_ms) {
    while (!depth_frame_.isValid() || !color_frame_.isValid()) {
      int ready = -1;
      openni::Status rc = openni::STATUS_TIME_OUT;
      if (is_file_) {
        rc = openni::OpenNI::waitForAnyStream(streams, 2, &ready, timeout_ms);
        if (rc == openni::STATUS_TIME_OUT || ready < 0) {
          throw Error(Format(spec_, ": no ", depth_frame_.isValid() ? "colour" : "depth",
                             " frame within ", capture_.frame_timeout, " s after frame ",
                             depth_read_, " of ", total_, " (unplayable recording)"));
        }
      } else {
        // Only the stream whose frame is missing is read: a newer frame of the other stream must
        // not replace the one waiting for its partner (when a camera delivers depth before colour
        // at every tick, colour a frame behind would otherwise never catch up). Waits in slices,
        // so that an unplugged camera ends the capture at once.
        const int first = depth_frame_.isValid() ? 1 : 0;
        const int count = depth_frame_.isValid() || color_frame_.isValid() ? 1 : 2;
        bool attached = true;
        for (int waited = 0; waited < timeout_ms && rc == openni::STATUS_TIME_OUT && attached;) {
          const int slice = std::min(kWaitSliceMs, timeout_ms - waited);
          rc = openni::OpenNI::waitForAnyStream(streams + first, count, &ready, slice);
          waited += slice;
          if (rc != openni::STATUS_OK) attached = StillAttached(uri_);
        }
        if (ready >= 0) ready += first;
        if (!attached) {
          EndLive("the camera was disconnected");
          return false;
        }
        if (rc == openni::STATUS_TIME_OUT || ready < 0) {
          EndLive(Format("no ", depth_frame_.isValid() ? "colour" : "depth", " frame within ",
                         capture_.frame_timeout, " s (camera stalled)"));
          return false;
        }
      }
      if (rc != openni::STATUS_OK)
        throw Error(Format(spec_, ": waiting for frames failed: ", LastOpenNI2Error()));
      openni::VideoFrameRef frame;
      if (streams[ready]->readFrame(&frame) != openni::STATUS_OK) {
        throw Error(Format(spec_, ": reading a frame failed: ", LastOpenNI2Error()));
      }
      if (ready == 0) {
        depth_frame_ = frame;
        ++depth_read_;
      } else {
        color_frame_ = frame;
        ++color_read_;
      }
    }
    return true;
  }

  RgbdFrame ToRgbdFrame() const {
    RgbdFrame out;
    out.timestamp = depth_frame_.getTimestamp() * 1e-6;
    out.intrinsics = intrinsics_;
    out.depth = ImageDepth(width_, height_);
    out.color = ImageRgb(width_, height_);
    const std::string where = Format(spec_, ": frame ", next_index_);
    for (const openni::VideoFrameRef* f : {&depth_frame_, &color_frame_}) {
      if (f->getWidth() != width_ || f->getHeight() != height_) {
        throw Error(Format(where, ": a ", f == &depth_frame_ ? "depth" : "colour", " frame of ",
                           f->getWidth(), "x", f->getHeight(), " in a ", width_, "x", height_,
                           " stream"));
      }
    }
    // Depth: millimetres (or 100 um units) -> meters.
    const openni::PixelFormat df = depth_frame_.getVideoMode().getPixelFormat();
    if (df != openni::PIXEL_FORMAT_DEPTH_1_MM && df != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      throw Error(Format(where, ": depth pixel format ", static_cast<int>(df),
                         " is not DEPTH_1_MM or DEPTH_100_UM"));
    }
    // Divided in double and then rounded to float, exactly as core's folder reader does, so that a
    // recording and a TUM folder of the same millimetres give bit-identical depth maps.
    const double units_per_meter = df == openni::PIXEL_FORMAT_DEPTH_1_MM ? 1000.0 : 10000.0;
    const auto* depth_bytes = static_cast<const uint8_t*>(depth_frame_.getData());
    for (int v = 0; v < height_; ++v) {
      const auto* row = reinterpret_cast<const uint16_t*>(
          depth_bytes + static_cast<size_t>(v) * depth_frame_.getStrideInBytes());
      for (int u = 0; u < width_; ++u)
        out.depth(mirrored_depth_ ? width_ - 1 - u : u, v) =
            static_cast<float>(row[u] / units_per_meter);
    }
    // Colour: RGB888 code values -> linear with the camera response.
    if (color_frame_.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888) {
      throw Error(Format(where, ": colour pixel format ",
                         static_cast<int>(color_frame_.getVideoMode().getPixelFormat()),
                         " is not RGB888"));
    }
    const auto* color_bytes = static_cast<const uint8_t*>(color_frame_.getData());
    for (int v = 0; v < height_; ++v) {
      const uint8_t* row = color_bytes + static_cast<size_t>(v) * color_frame_.getStrideInBytes();
      for (int u = 0; u < width_; ++u) {
        out.color(mirrored_color_ ? width_ - 1 - u : u, v) = {
            to_linear_[row[3 * u]], to_linear_[row[3 * u + 1]], to_linear_[row[3 * u + 2]]};
      }
    }
    out.Validate();
    return out;
  }

  std::string spec_;
  SourceOptions options_;
  CaptureOptions capture_;
  std::array<float, 256> to_linear_;
  bool is_file_ = false;
  bool mirrored_depth_ = false, mirrored_color_ = false;  // a recording's xnMirror: flipped back
  bool any_started_ = false;  // a stream was started (the player may hold a frame; see Close)
  bool pair_by_time_ = true;  // live cameras: pair frames by time stamp (see ReadPair)
  static constexpr int kEndOfFileWaitMs = 2000;
  static constexpr int kWaitSliceMs = 100;  // live cameras: how often a wait looks for an unplug
  std::string uri_;     // a live camera's URI (to see whether it is still attached)
  bool ended_ = false;  // a live camera's stream has ended (unplugged or stalled)
  size_t pairs_read_ = 0, skipped_ = 0;  // live cameras: pairs read, camera frames never paired
  int64_t first_camera_index_ = 0;
  std::optional<EndOfFileListener> eof_listener_;  // recordings only (see Close)
  bool eof_listener_registered_ = false;
  openni::Device device_;
  // Wrappers that do not own their stream handles: Close decides whether a handle is destroyed.
  std::optional<openni::VideoStream> depth_, color_;
  openni::VideoFrameRef depth_frame_, color_frame_;
  int width_ = 0, height_ = 0;
  int total_ = 0;                          // frames in a recording (pairs: the smaller count)
  int depth_total_ = 0, color_total_ = 0;  // frames of each stream in a recording
  int depth_read_ = 0, color_read_ = 0;    // frames read from each stream so far
  int next_index_ = 0;                     // index of the next frame pair to read
  size_t emitted_ = 0;
  CameraIntrinsics intrinsics_;
  Trajectory no_poses_;
};

}  // namespace

std::unique_ptr<FrameSource> OpenOpenNI2Source(const std::string& spec,
                                               const SourceOptions& options,
                                               const CaptureOptions& capture) {
  options.Validate();
  capture.Validate();
  if (!IsOpenNI2Spec(spec))
    throw Error(Format(spec, ": not an OpenNI2 source (openni2, openni2:URI or a .oni file)"));
  if (!options.trajectory.empty()) {
    throw Error(Format(
        spec, ": option trajectory is not supported for OpenNI2 sources (frames carry no poses)"));
  }
  return std::make_unique<OpenNI2Source>(spec, options, capture);
}

std::unique_ptr<FrameSource> OpenAnySource(const std::string& spec, const SourceOptions& options,
                                           const CaptureOptions& capture) {
  if (IsOpenNI2Spec(spec)) return Undistorted(OpenOpenNI2Source(spec, options, capture));
  return OpenFrameSource(spec, options);
}

}  // namespace genscene::capture
