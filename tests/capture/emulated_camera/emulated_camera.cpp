// An OpenNI2 driver that emulates a depth + colour camera by streaming a TUM folder, for tests of
// the live camera path: OpenNI2 loads it like any camera driver (from OpenNI2/Drivers next to the
// libOpenNI2.so in use), lists one device, and the device streams in real time.
//
// GENSCENE_EMULATED_CAMERA=FOLDER names the TUM folder (rgb.txt, depth.txt, rgb/*.png,
// depth/*.png at 5000 units per metre). Entries whose image file is missing are skipped, and the
// i-th remaining depth image is paired with the i-th remaining colour image. Without the variable
// the driver lists no device.
//
// The device: depth (DEPTH_1_MM, depth units rounded to the nearest millimetre) and colour
// (RGB888), 640x480 and 320x240 (every second pixel of every second row) at 30 Hz, one thread per
// started stream. Frame n of a stream (n = 0, 1, ...) is delivered at start + n / 30 s with
// frameIndex n + 1 and timestamp n * 1e6 / 30 us, and shows folder frame n modulo the folder's
// frame count: the camera loops and never ends by itself. Registration (depth to colour: the
// frames already are) and frame sync are accepted; mirroring is accepted off only.
//
// GENSCENE_EMULATED_FAULT selects one misbehaviour:
//   drop=K        frames K-1, 2K-1, ... (every K-th) are not delivered, on both streams;
//   drop_color=K  the same on the colour stream only;
//   out_of_step   the colour stream is a frame behind: colour frame n shows (and is numbered as)
//                 folder frame n - 1, and there is no colour frame 0;
//   stall=F       after F frames the streams deliver nothing more, and the device stays connected;
//   disconnect=F  after F frames the device is reported disconnected (DriverBase::
//                 deviceDisconnected, as a driver does on unplug) and nothing more is delivered;
//   no_color      the device has a depth sensor only;
//   bad_modes     the sensors offer only 1280x1024 @ 30 and 640x480 @ 60 Hz.
#include <Driver/OniDriverAPI.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

// ONI_EXPORT_DRIVER allocates the driver with OpenNI2's XnLib macros, which libopenni2-dev does
// not ship.
#define XN_NEW(type, arg) new type(arg)
#define XN_DELETE(p) delete (p)

namespace {

namespace fs = std::filesystem;
using oni::driver::DeviceBase;
using oni::driver::DriverBase;
using oni::driver::StreamBase;

constexpr const char* kUri = "genscene-emulated://0";
constexpr int kFps = 30;
constexpr double kFx = 525.0;  // focal length in pixels at 640x480 (TUM's default)

struct Fault {
  enum Kind {
    kNone,
    kDrop,
    kDropColor,
    kOutOfStep,
    kStall,
    kDisconnect,
    kNoColor,
    kBadModes
  } kind = kNone;
  int n = 0;

  static Fault Parse(const char* text) {
    Fault f;
    if (text == nullptr || *text == '\0') return f;
    const std::string s(text);
    const auto value = [&](const char* prefix, Kind kind) {
      const size_t len = std::strlen(prefix);
      if (s.compare(0, len, prefix) != 0) return false;
      f.kind = kind;
      f.n = std::atoi(s.c_str() + len);
      return true;
    };
    if (value("drop=", kDrop) || value("drop_color=", kDropColor) || value("stall=", kStall) ||
        value("disconnect=", kDisconnect)) {
      if ((f.kind == kDrop || f.kind == kDropColor) && f.n < 1) f.n = 1;
      return f;
    }
    if (s == "out_of_step") f.kind = kOutOfStep;
    if (s == "no_color") f.kind = kNoColor;
    if (s == "bad_modes") f.kind = kBadModes;
    return f;
  }
};

// The folder's frames at 640x480: depth in millimetres, colour as RGB bytes.
struct Frames {
  std::vector<std::vector<uint16_t>> depth_mm;
  std::vector<std::vector<uint8_t>> rgb;
  size_t size() const { return depth_mm.size(); }
};

std::vector<fs::path> ListedImages(const fs::path& folder, const char* list) {
  std::ifstream in(folder / list);
  std::vector<fs::path> files;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string timestamp, file;
    if (!(fields >> timestamp >> file)) continue;
    std::error_code ec;
    if (fs::is_regular_file(folder / file, ec)) files.push_back(folder / file);
  }
  return files;
}

// Reads the folder; the error message (empty on success) goes to `error`.
Frames LoadFrames(const fs::path& folder, std::string* error) {
  Frames frames;
  const std::vector<fs::path> depth = ListedImages(folder, "depth.txt");
  const std::vector<fs::path> rgb = ListedImages(folder, "rgb.txt");
  const size_t count = std::min(depth.size(), rgb.size());
  if (count == 0) {
    *error = "emulated camera: no frames in " + folder.string() + " (rgb.txt, depth.txt)";
    return frames;
  }
  for (size_t i = 0; i < count; ++i) {
    const cv::Mat d = cv::imread(depth[i].string(), cv::IMREAD_UNCHANGED);
    const cv::Mat c = cv::imread(rgb[i].string(), cv::IMREAD_COLOR);
    if (d.type() != CV_16UC1 || d.cols != 640 || d.rows != 480 || c.cols != 640 || c.rows != 480) {
      *error = "emulated camera: " + depth[i].string() + " / " + rgb[i].string() +
               " are not a 640x480 16-bit depth image and a 640x480 colour image";
      return Frames();
    }
    std::vector<uint16_t> mm(640 * 480);
    for (int v = 0; v < 480; ++v) {
      for (int u = 0; u < 640; ++u) {
        // 5000 units per metre -> millimetres, to the nearest (5 is odd: no ties).
        mm[v * 640 + u] = static_cast<uint16_t>((d.at<uint16_t>(v, u) + 2) / 5);
      }
    }
    cv::Mat rgb_mat;
    cv::cvtColor(c, rgb_mat, cv::COLOR_BGR2RGB);
    frames.depth_mm.push_back(std::move(mm));
    frames.rgb.emplace_back(rgb_mat.data, rgb_mat.data + 640 * 480 * 3);
  }
  return frames;
}

std::vector<OniVideoMode> ModesOf(OniSensorType sensor, const Fault& fault) {
  const OniPixelFormat format =
      sensor == ONI_SENSOR_DEPTH ? ONI_PIXEL_FORMAT_DEPTH_1_MM : ONI_PIXEL_FORMAT_RGB888;
  if (fault.kind == Fault::kBadModes) return {{format, 1280, 1024, 30}, {format, 640, 480, 60}};
  return {{format, 640, 480, kFps}, {format, 320, 240, kFps}};
}

class EmulatedDevice;

// What every stream of a device shares: the frames, the fault, and the disconnect report.
struct DeviceState {
  Frames frames;
  Fault fault;
  OniDeviceInfo info{};
  std::function<void()> report_disconnect;  // called once, from a stream thread
  std::once_flag disconnect_once;
};

class EmulatedStream : public StreamBase {
 public:
  EmulatedStream(OniSensorType sensor, DeviceState* device)
      : sensor_(sensor), device_(device), mode_(ModesOf(sensor, device->fault)[0]) {}
  ~EmulatedStream() override { stop(); }

  OniStatus start() override {
    stop();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = false;
    }
    thread_ = std::thread([this] { Run(); });
    return ONI_STATUS_OK;
  }

  void stop() override {
    if (!thread_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }

  int getRequiredFrameSize() override {
    return mode_.resolutionX * mode_.resolutionY * BytesPerPixel();
  }

  OniBool isPropertySupported(int id) override {
    return id == ONI_STREAM_PROPERTY_VIDEO_MODE || id == ONI_STREAM_PROPERTY_MIRRORING ||
           id == ONI_STREAM_PROPERTY_HORIZONTAL_FOV || id == ONI_STREAM_PROPERTY_VERTICAL_FOV;
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE:
        return Put(mode_, data, size);
      case ONI_STREAM_PROPERTY_MIRRORING:
        return Put(static_cast<OniBool>(FALSE), data, size);
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
        return Put(static_cast<float>(2.0 * std::atan(320.0 / kFx)), data, size);
      case ONI_STREAM_PROPERTY_VERTICAL_FOV:
        return Put(static_cast<float>(2.0 * std::atan(240.0 / kFx)), data, size);
      default:
        return ONI_STATUS_NOT_SUPPORTED;
    }
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    if (id == ONI_STREAM_PROPERTY_VIDEO_MODE && size == sizeof(OniVideoMode)) {
      OniVideoMode wanted;
      std::memcpy(&wanted, data, sizeof wanted);
      for (const OniVideoMode& m : ModesOf(sensor_, device_->fault)) {
        if (m.pixelFormat == wanted.pixelFormat && m.resolutionX == wanted.resolutionX &&
            m.resolutionY == wanted.resolutionY && m.fps == wanted.fps) {
          if (thread_.joinable()) return ONI_STATUS_OUT_OF_FLOW;  // not while streaming
          mode_ = m;
          return ONI_STATUS_OK;
        }
      }
      return ONI_STATUS_NOT_SUPPORTED;
    }
    if (id == ONI_STREAM_PROPERTY_MIRRORING && size == sizeof(OniBool)) {
      OniBool on;
      std::memcpy(&on, data, sizeof on);
      return on ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    return ONI_STATUS_NOT_SUPPORTED;
  }

 private:
  template <typename T>
  static OniStatus Put(const T& value, void* data, int* size) {
    if (*size < static_cast<int>(sizeof(T))) return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &value, sizeof(T));
    *size = sizeof(T);
    return ONI_STATUS_OK;
  }

  int BytesPerPixel() const { return sensor_ == ONI_SENSOR_DEPTH ? 2 : 3; }

  // The stream thread: frame n at start + n / 30 s until stopped.
  void Run() {
    const Fault& fault = device_->fault;
    const auto start = std::chrono::steady_clock::now();
    for (int n = 0;; ++n) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        const auto due = start + std::chrono::microseconds(int64_t{1000000} * n / kFps);
        if (wake_.wait_until(lock, due, [this] { return stopping_; })) return;
      }
      if ((fault.kind == Fault::kStall || fault.kind == Fault::kDisconnect) && n >= fault.n) {
        if (fault.kind == Fault::kDisconnect && device_->report_disconnect)
          std::call_once(device_->disconnect_once, device_->report_disconnect);
        continue;  // nothing more is delivered; wait for stop
      }
      if (fault.kind == Fault::kDrop && n % fault.n == fault.n - 1) continue;
      if (fault.kind == Fault::kDropColor && sensor_ == ONI_SENSOR_COLOR &&
          n % fault.n == fault.n - 1)
        continue;
      int shown = n;
      if (fault.kind == Fault::kOutOfStep && sensor_ == ONI_SENSOR_COLOR) {
        if (n == 0) continue;
        shown = n - 1;
      }
      Deliver(n, shown);
    }
  }

  void Deliver(int n, int shown) {
    OniFrame* frame = getServices().acquireFrame();
    if (frame == nullptr) return;
    const int w = mode_.resolutionX, h = mode_.resolutionY, bpp = BytesPerPixel();
    const int step = 640 / w;  // 1 at 640x480, 2 at 320x240
    const Frames& frames = device_->frames;
    const size_t f = static_cast<size_t>(shown) % frames.size();
    auto* out = static_cast<uint8_t*>(frame->data);
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const size_t src = static_cast<size_t>(v * step) * 640 + static_cast<size_t>(u * step);
        uint8_t* dst = out + (static_cast<size_t>(v) * w + u) * bpp;
        if (sensor_ == ONI_SENSOR_DEPTH)
          std::memcpy(dst, &frames.depth_mm[f][src], 2);
        else
          std::memcpy(dst, &frames.rgb[f][3 * src], 3);
      }
    }
    frame->dataSize = w * h * bpp;
    frame->sensorType = sensor_;
    frame->frameIndex = shown + 1;
    frame->timestamp = static_cast<uint64_t>(int64_t{1000000} * shown / kFps);
    frame->width = w;
    frame->height = h;
    frame->videoMode = mode_;
    frame->croppingEnabled = FALSE;
    frame->cropOriginX = 0;
    frame->cropOriginY = 0;
    frame->stride = w * bpp;
    raiseNewFrame(frame);
    getServices().releaseFrame(frame);
  }

  const OniSensorType sensor_;
  DeviceState* const device_;
  OniVideoMode mode_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
};

class EmulatedDevice : public DeviceBase {
 public:
  explicit EmulatedDevice(std::unique_ptr<DeviceState> state) : state_(std::move(state)) {
    sensor_modes_.push_back(ModesOf(ONI_SENSOR_DEPTH, state_->fault));
    sensors_.push_back(
        {ONI_SENSOR_DEPTH, static_cast<int>(sensor_modes_[0].size()), sensor_modes_[0].data()});
    if (state_->fault.kind != Fault::kNoColor) {
      sensor_modes_.push_back(ModesOf(ONI_SENSOR_COLOR, state_->fault));
      sensors_.push_back(
          {ONI_SENSOR_COLOR, static_cast<int>(sensor_modes_[1].size()), sensor_modes_[1].data()});
    }
  }
  ~EmulatedDevice() override {
    for (auto& s : streams_) s->stop();
  }

  OniStatus getSensorInfoList(OniSensorInfo** infos, int* count) override {
    *infos = sensors_.data();
    *count = static_cast<int>(sensors_.size());
    return ONI_STATUS_OK;
  }

  StreamBase* createStream(OniSensorType sensor) override {
    const bool has = std::any_of(sensors_.begin(), sensors_.end(),
                                 [&](const OniSensorInfo& s) { return s.sensorType == sensor; });
    if (!has) return nullptr;
    std::lock_guard<std::mutex> lock(mutex_);
    streams_.push_back(std::make_unique<EmulatedStream>(sensor, state_.get()));
    return streams_.back().get();
  }

  void destroyStream(StreamBase* stream) override {
    std::unique_ptr<EmulatedStream> doomed;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = std::find_if(streams_.begin(), streams_.end(),
                             [&](const auto& s) { return s.get() == stream; });
      if (it == streams_.end()) return;
      doomed = std::move(*it);
      streams_.erase(it);
    }
    // Destroyed (its thread joined) outside the lock.
  }

  OniBool isImageRegistrationModeSupported(OniImageRegistrationMode mode) override {
    return mode == ONI_IMAGE_REGISTRATION_OFF || mode == ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  }

  OniBool isPropertySupported(int id) override {
    return id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION;
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION) return ONI_STATUS_NOT_SUPPORTED;
    if (*size < static_cast<int>(sizeof(OniImageRegistrationMode))) return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &registration_, sizeof registration_);
    *size = sizeof registration_;
    return ONI_STATUS_OK;
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION ||
        size != static_cast<int>(sizeof(OniImageRegistrationMode)))
      return ONI_STATUS_NOT_SUPPORTED;
    OniImageRegistrationMode mode;
    std::memcpy(&mode, data, sizeof mode);
    if (!isImageRegistrationModeSupported(mode)) return ONI_STATUS_NOT_SUPPORTED;
    registration_ = mode;
    return ONI_STATUS_OK;
  }

 private:
  std::unique_ptr<DeviceState> state_;
  std::vector<std::vector<OniVideoMode>> sensor_modes_;
  std::vector<OniSensorInfo> sensors_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<EmulatedStream>> streams_;
  OniImageRegistrationMode registration_ = ONI_IMAGE_REGISTRATION_OFF;
};

class EmulatedDriver : public DriverBase {
 public:
  explicit EmulatedDriver(OniDriverServices* services) : DriverBase(services) {}

  OniStatus initialize(oni::driver::DeviceConnectedCallback connected,
                       oni::driver::DeviceDisconnectedCallback disconnected,
                       oni::driver::DeviceStateChangedCallback state_changed,
                       void* cookie) override {
    const OniStatus rc = DriverBase::initialize(connected, disconnected, state_changed, cookie);
    if (rc != ONI_STATUS_OK) return rc;
    const char* folder = std::getenv("GENSCENE_EMULATED_CAMERA");
    if (folder == nullptr || *folder == '\0') return ONI_STATUS_OK;  // no camera
    folder_ = folder;
    std::snprintf(info_.uri, sizeof info_.uri, "%s", kUri);
    std::snprintf(info_.vendor, sizeof info_.vendor, "%s", "genscene");
    std::snprintf(info_.name, sizeof info_.name, "%s", "Emulated RGB-D camera");
    info_.usbVendorId = 0;
    info_.usbProductId = 0;
    deviceConnected(&info_);
    return ONI_STATUS_OK;
  }

  DeviceBase* deviceOpen(const char* uri, const char* /*mode*/) override {
    if (folder_.empty() || uri == nullptr || std::strcmp(uri, kUri) != 0) return nullptr;
    std::lock_guard<std::mutex> lock(mutex_);
    if (device_) {
      getServices().errorLoggerAppend("emulated camera: the device is already open");
      return nullptr;
    }
    auto state = std::make_unique<DeviceState>();
    std::string error;
    state->frames = LoadFrames(folder_, &error);
    if (!error.empty()) {
      getServices().errorLoggerAppend("%s", error.c_str());
      return nullptr;
    }
    state->fault = Fault::Parse(std::getenv("GENSCENE_EMULATED_FAULT"));
    state->info = info_;
    state->report_disconnect = [this] { deviceDisconnected(&info_); };
    device_ = std::make_unique<EmulatedDevice>(std::move(state));
    return device_.get();
  }

  void deviceClose(DeviceBase* device) override {
    std::unique_ptr<EmulatedDevice> doomed;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (device != device_.get()) return;
      doomed = std::move(device_);
    }
  }

  OniStatus tryDevice(const char* uri) override {
    return (!folder_.empty() && uri != nullptr && std::strcmp(uri, kUri) == 0) ? ONI_STATUS_OK
                                                                               : ONI_STATUS_ERROR;
  }

  // Frames of one index come from the same folder frame on every stream already: the group is a
  // token only.
  void* enableFrameSync(StreamBase** /*streams*/, int /*count*/) override { return new int(0); }
  void disableFrameSync(void* group) override { delete static_cast<int*>(group); }

  void shutdown() override {
    std::unique_ptr<EmulatedDevice> doomed;
    std::lock_guard<std::mutex> lock(mutex_);
    doomed = std::move(device_);
  }

 private:
  std::string folder_;
  OniDeviceInfo info_{};
  std::mutex mutex_;
  std::unique_ptr<EmulatedDevice> device_;
};

}  // namespace

ONI_EXPORT_DRIVER(EmulatedDriver)
