#include "core/frame_source.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/se3.h"

namespace genscene {

namespace fs = std::filesystem;

void SourceOptions::Validate() const {
  if (!(depth_scale == 0.0 || (depth_scale >= 1.0 && depth_scale <= 1e6))) {
    throw Error(
        Format("option depth_scale = ", depth_scale, " is not 0 (format default) or in [1, 1e6]"));
  }
  RequireOneOf("depth_encoding", depth_encoding, {"scaled", "nyu-disparity", "sun"});
  CameraResponse::Parse(camera_response, "option camera_response");
  RequireRange("max_time_difference", max_time_difference, 0.0, 10.0);
  RequireRange("first_frame", first_frame, 0, 1 << 30);
  RequireRange("max_frames", max_frames, 0, 1 << 30);
  RequireRange("stride", stride, 1, 1 << 20);
}

namespace {

// One frame of a listed sequence, before decoding.
struct FrameEntry {
  double timestamp = 0.0;
  fs::path color;  // empty: no colour
  fs::path depth;  // empty: no depth
};

// A sequence whose files are known up front (TUM folders, view sets, Redwood folders).
class ListedFrameSource : public FrameSource {
 public:
  ListedFrameSource(std::string description, std::vector<FrameEntry> entries,
                    CameraIntrinsics intrinsics, DepthEncoding encoding, CameraResponse response,
                    Trajectory poses, double max_pose_difference, bool poses_by_index)
      : description_(std::move(description)),
        entries_(std::move(entries)),
        intrinsics_(intrinsics),
        encoding_(encoding),
        response_(response),
        poses_(std::move(poses)),
        max_pose_difference_(max_pose_difference),
        poses_by_index_(poses_by_index) {}

  std::string Describe() const override {
    return Format(description_, " (", entries_.size(), " frames, ", intrinsics_.width, "x",
                  intrinsics_.height, poses_.empty() ? "" : ", with poses", ")");
  }
  std::optional<size_t> FrameCount() const override { return entries_.size(); }
  const CameraIntrinsics& Intrinsics() const override { return intrinsics_; }
  const Trajectory& KnownPoses() const override { return poses_; }

  std::optional<RgbdFrame> Next() override {
    if (next_ >= entries_.size()) return std::nullopt;
    const FrameEntry& e = entries_[next_++];
    RgbdFrame frame;
    frame.timestamp = e.timestamp;
    frame.intrinsics = intrinsics_;
    frame.color_path = e.color.string();
    frame.depth_path = e.depth.string();
    if (!e.color.empty()) frame.color = ReadColorImage(e.color, response_);
    if (!e.depth.empty()) frame.depth = ReadDepthImage(e.depth, encoding_);
    if (!frame.color.empty() && !frame.depth.empty() && !frame.color.SameSize(frame.depth)) {
      throw Error(Format(e.depth.string(), ": depth ", frame.depth.width(), "x",
                         frame.depth.height(), " but colour ", e.color.string(), " is ",
                         frame.color.width(), "x", frame.color.height()));
    }
    frame.world_from_camera = PoseOf(next_ - 1, e.timestamp);
    frame.Validate();
    return frame;
  }

 private:
  std::optional<Eigen::Isometry3d> PoseOf(size_t index, double timestamp) const {
    if (poses_.empty()) return std::nullopt;
    if (poses_by_index_) {  // stamped with their frames' own time stamps
      if (auto p = poses_.Nearest(timestamp, 0.0)) return p->world_from_camera;
      return std::nullopt;
    }
    // Interpolate between bracketing ground-truth poses when they are close; else the nearest.
    if (auto p = poses_.Interpolate(timestamp, 2.0 * max_pose_difference_)) return p;
    if (auto p = poses_.Nearest(timestamp, max_pose_difference_)) return p->world_from_camera;
    return std::nullopt;
  }

  std::string description_;
  std::vector<FrameEntry> entries_;
  CameraIntrinsics intrinsics_;
  DepthEncoding encoding_;
  CameraResponse response_;
  Trajectory poses_;
  double max_pose_difference_;
  bool poses_by_index_;
  size_t next_ = 0;
};

struct TimedPath {
  double timestamp;
  std::string path;
};

// A TUM list: lines `timestamp path`.
std::vector<TimedPath> ReadTimedList(const fs::path& list) {
  std::vector<TimedPath> out;
  for (const TextLine& line : ReadDataLines(list)) {
    const std::string where = Format(list.string(), ":", line.number);
    const auto tokens = SplitWhitespace(line.text);
    if (tokens.size() != 2)
      throw Error(Format(where, ": expected 'timestamp path', got ", tokens.size(), " fields"));
    out.push_back({ParseDouble(tokens[0], where), tokens[1]});
  }
  if (out.empty()) throw Error(Format(list.string(), ": empty list (no frames)"));
  return out;
}

// TUM associate.py: all pairs closer than max_difference, taken greedily by increasing time
// difference, each stamp used once; result sorted by the first stamp.
std::vector<std::pair<size_t, size_t>> AssociateByTime(const std::vector<TimedPath>& a,
                                                       const std::vector<TimedPath>& b,
                                                       double max_difference) {
  struct Candidate {
    double difference;
    size_t i, j;
  };
  std::vector<Candidate> candidates;
  std::vector<size_t> order_b(b.size());
  for (size_t j = 0; j < b.size(); ++j) order_b[j] = j;
  std::sort(order_b.begin(), order_b.end(),
            [&](size_t x, size_t y) { return b[x].timestamp < b[y].timestamp; });
  for (size_t i = 0; i < a.size(); ++i) {
    const double t = a[i].timestamp;
    auto lo = std::lower_bound(order_b.begin(), order_b.end(), t - max_difference,
                               [&](size_t j, double time) { return b[j].timestamp < time; });
    for (auto it = lo; it != order_b.end() && b[*it].timestamp <= t + max_difference; ++it) {
      const double d = std::abs(b[*it].timestamp - t);
      if (d < max_difference || (max_difference == 0.0 && d == 0.0))
        candidates.push_back({d, i, *it});
    }
  }
  std::stable_sort(
      candidates.begin(), candidates.end(),
      [](const Candidate& x, const Candidate& y) { return x.difference < y.difference; });
  std::vector<bool> used_a(a.size(), false), used_b(b.size(), false);
  std::vector<std::pair<size_t, size_t>> matches;
  for (const Candidate& c : candidates) {
    if (used_a[c.i] || used_b[c.j]) continue;
    used_a[c.i] = used_b[c.j] = true;
    matches.emplace_back(c.i, c.j);
  }
  std::sort(matches.begin(), matches.end(), [&](const auto& x, const auto& y) {
    return a[x.first].timestamp < a[y.first].timestamp;
  });
  return matches;
}

// The entries of a TUM list whose files are in the folder. An excerpt of a sequence keeps the
// sequence's full lists and the files of one stretch of it: the entries outside that stretch
// are dropped (counted in `dropped`); a file missing inside it is a damaged copy, an error.
std::vector<TimedPath> PresentStretch(const std::vector<TimedPath>& list, const fs::path& list_path,
                                      size_t* dropped) {
  std::error_code ec;
  std::vector<bool> present(list.size());
  for (size_t i = 0; i < list.size(); ++i) {
    present[i] = fs::is_regular_file(ResolveRelativeTo(list_path, list[i].path), ec);
  }
  const auto first = std::find(present.begin(), present.end(), true);
  if (first == present.end()) {
    throw Error(Format(list_path.string(), ": lists ", list.size(),
                       " files and none exists (first: ",
                       ResolveRelativeTo(list_path, list.front().path).string(), ")"));
  }
  const size_t begin = static_cast<size_t>(first - present.begin());
  size_t end = list.size();
  while (!present[end - 1]) --end;
  for (size_t i = begin; i < end; ++i) {
    if (!present[i]) {
      throw Error(Format(list_path.string(), ": lists ",
                         ResolveRelativeTo(list_path, list[i].path).string(),
                         " which does not exist (between files that do)"));
    }
  }
  *dropped = list.size() - (end - begin);
  return {list.begin() + static_cast<std::ptrdiff_t>(begin),
          list.begin() + static_cast<std::ptrdiff_t>(end)};
}

fs::path RequireFile(const fs::path& path, const fs::path& listed_in) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw Error(Format(listed_in.string(), ": lists ", path.string(), " which does not exist"));
  }
  return path;
}

// Poses file by content: Redwood .log, TUM (8 columns), or one `tx ty tz qx qy qz qw` per frame
// (7 columns; timestamps = frame index).
Trajectory ReadPosesFile(const fs::path& path, bool* by_index) {
  if (path.extension() == ".log") {
    *by_index = true;
    return ReadRedwoodLog(path);
  }
  const auto lines = ReadDataLines(path);
  if (!lines.empty() && SplitWhitespace(lines[0].text).size() == 7) {
    *by_index = true;
    Trajectory poses;
    for (size_t i = 0; i < lines.size(); ++i) {
      const std::string where = Format(path.string(), ":", lines[i].number);
      const auto t = SplitWhitespace(lines[i].text);
      if (t.size() != 7)
        throw Error(Format(where, ": expected 'tx ty tz qx qy qz qw', got ", t.size(), " values"));
      double v[7];
      for (int k = 0; k < 7; ++k) v[k] = ParseDouble(t[k], where);
      try {
        poses.Add(static_cast<double>(i),
                  PoseFromTranslationQuaternion({v[0], v[1], v[2]},
                                                Eigen::Quaterniond(v[6], v[3], v[4], v[5])));
      } catch (const Error& e) {
        throw Error(Format(where, ": ", e.what()));
      }
    }
    return poses;
  }
  *by_index = false;
  return ReadTumTrajectory(path);
}

DepthEncoding MakeEncoding(const SourceOptions& options, double default_scale) {
  DepthEncoding encoding;
  encoding.scale = options.depth_scale > 0.0 ? options.depth_scale : default_scale;
  if (options.depth_encoding == "nyu-disparity") encoding.kind = DepthEncoding::Kind::kNyuDisparity;
  if (options.depth_encoding == "sun") encoding.kind = DepthEncoding::Kind::kSunRotated;
  return encoding;
}

// Applies first_frame / stride / max_frames.
std::vector<FrameEntry> SelectFrames(const std::vector<FrameEntry>& all,
                                     const SourceOptions& options, const std::string& source) {
  std::vector<FrameEntry> out;
  for (size_t i = options.first_frame; i < all.size(); i += options.stride) {
    if (options.max_frames > 0 && out.size() >= static_cast<size_t>(options.max_frames)) break;
    out.push_back(all[i]);
  }
  if (out.empty()) {
    throw Error(Format(source, ": no frames to read (", all.size(), " frames, first_frame ",
                       options.first_frame, ")"));
  }
  return out;
}

// Guesses the TUM camera from the folder name (rgbd_dataset_freiburg2_xyz, tum-fr1desk, ...).
std::optional<std::string> GuessTumCamera(const fs::path& folder) {
  std::string name = fs::absolute(folder).lexically_normal().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  for (const char* camera : {"1", "2", "3"}) {
    if (name.find(std::string("freiburg") + camera) != std::string::npos ||
        name.find(std::string("fr") + camera) != std::string::npos) {
      return std::string("tum") + camera;
    }
  }
  return std::nullopt;
}

std::unique_ptr<FrameSource> OpenTumFolder(const fs::path& folder, const SourceOptions& options) {
  const fs::path rgb_list = folder / "rgb.txt";
  const fs::path depth_list = folder / "depth.txt";
  std::error_code ec;
  std::vector<FrameEntry> entries;
  if (!options.associations.empty()) {
    const fs::path assoc = options.associations;
    for (const TextLine& line : ReadDataLines(assoc)) {
      const std::string where = Format(assoc.string(), ":", line.number);
      const auto t = SplitWhitespace(line.text);
      if (t.size() != 4)
        throw Error(Format(where, ": expected 't_rgb rgb_path t_depth depth_path', got ", t.size(),
                           " fields"));
      // TUM associations name files relative to the dataset folder.
      entries.push_back({ParseDouble(t[0], where), RequireFile(folder / t[1], assoc),
                         RequireFile(folder / t[3], assoc)});
    }
    if (entries.empty())
      throw Error(Format(assoc.string(), ": empty associations file (no frames)"));
  } else
    try {
      size_t rgb_dropped = 0, depth_dropped = 0;
      const auto rgb = PresentStretch(ReadTimedList(rgb_list), rgb_list, &rgb_dropped);
      if (!fs::exists(depth_list, ec)) {
        if (rgb_dropped > 0) {
          spdlog::warn(
              "{}: an excerpt: rgb.txt lists {} frames, {} of them are here; reading those",
              folder.string(), rgb.size() + rgb_dropped, rgb.size());
        }
        for (const auto& r : rgb)
          entries.push_back(
              {r.timestamp, RequireFile(ResolveRelativeTo(rgb_list, r.path), rgb_list), {}});
      } else {
        const auto depth = PresentStretch(ReadTimedList(depth_list), depth_list, &depth_dropped);
        if (rgb_dropped + depth_dropped > 0) {
          spdlog::warn(
              "{}: an excerpt: rgb.txt and depth.txt list {} and {} frames, {} and {} of them are "
              "here; "
              "reading those (--associations FILE to choose the pairs)",
              folder.string(), rgb.size() + rgb_dropped, depth.size() + depth_dropped, rgb.size(),
              depth.size());
        }
        const auto matches = AssociateByTime(rgb, depth, options.max_time_difference);
        if (matches.empty()) {
          throw Error(Format(folder.string(), ": no rgb/depth pair closer than ",
                             options.max_time_difference, " s"));
        }
        for (const auto& [i, j] : matches) {
          entries.push_back(
              {rgb[i].timestamp, RequireFile(ResolveRelativeTo(rgb_list, rgb[i].path), rgb_list),
               RequireFile(ResolveRelativeTo(depth_list, depth[j].path), depth_list)});
        }
      }
    } catch (const Error& e) {
      // An excerpt of a TUM sequence keeps the full lists; an associations file beside them may
      // name just the frames that are there.
      std::vector<std::string> lists;
      for (const auto& entry : fs::directory_iterator(folder, ec)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("assoc", 0) == 0 && entry.path().extension() == ".txt")
          lists.push_back(name);
      }
      if (lists.empty()) throw;
      std::sort(lists.begin(), lists.end());
      std::string names;
      for (const std::string& n : lists) names += (names.empty() ? "" : ", ") + n;
      throw Error(Format(e.what(), "; the folder has ", names,
                         ": give --associations FILE to read the pairs it lists"));
    }
  entries = SelectFrames(entries, options, folder.string());

  CameraIntrinsics intrinsics;
  if (!options.intrinsics.empty()) {
    intrinsics = ResolveIntrinsics(options.intrinsics);
  } else if (fs::exists(folder / "intrinsics.txt", ec)) {
    intrinsics = ReadIntrinsicsFile(folder / "intrinsics.txt");
  } else if (auto guess = GuessTumCamera(folder)) {
    spdlog::warn(
        "{}: no intrinsics given, using {} from the folder name (--intrinsics to give them)",
        folder.string(), *guess);
    intrinsics = *NamedIntrinsics(*guess);
  } else {
    throw Error(Format(folder.string(), ": no intrinsics.txt; give --intrinsics FILE or one of ",
                       NamedIntrinsicsList()));
  }

  Trajectory poses;
  bool by_index = false;
  if (!options.trajectory.empty()) {
    poses = ReadPosesFile(options.trajectory, &by_index);
    if (by_index) {  // pose i belongs to the i-th frame read, and takes its time stamp
      Trajectory stamped;
      for (size_t i = 0; i < entries.size(); ++i) {
        if (auto p = poses.Nearest(static_cast<double>(i), 0.0))
          stamped.Add(entries[i].timestamp, p->world_from_camera);
      }
      poses = stamped;
    }
  } else if (fs::exists(folder / "groundtruth.txt", ec)) {
    poses = ReadTumTrajectory(folder / "groundtruth.txt");
  }
  return std::make_unique<ListedFrameSource>(
      Format("TUM folder ", folder.string()), std::move(entries), intrinsics,
      MakeEncoding(options, 5000.0), CameraResponse::Parse(options.camera_response),
      std::move(poses), options.max_time_difference, by_index);
}

// Natural order: "2.png" before "10.png".
bool NaturalLess(const fs::path& a, const fs::path& b) {
  const std::string x = a.stem().string(), y = b.stem().string();
  const bool xd = !x.empty() && std::all_of(x.begin(), x.end(), ::isdigit);
  const bool yd = !y.empty() && std::all_of(y.begin(), y.end(), ::isdigit);
  if (xd && yd && x.size() != y.size()) return x.size() < y.size();
  return a.filename() < b.filename();
}

std::vector<fs::path> ListImages(const fs::path& dir) {
  static const std::vector<std::string> kExtensions = {".png", ".jpg", ".jpeg", ".pgm",
                                                       ".ppm", ".exr", ".tif",  ".tiff"};
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (std::find(kExtensions.begin(), kExtensions.end(), ext) != kExtensions.end())
      files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end(), NaturalLess);
  return files;
}

std::unique_ptr<FrameSource> OpenRedwoodFolder(const fs::path& folder, const fs::path& color_dir,
                                               const SourceOptions& options) {
  std::error_code ec;
  std::vector<FrameEntry> entries;
  const fs::path match = folder / "rgbd.match";
  if (fs::exists(match, ec)) {
    for (const TextLine& line : ReadDataLines(match)) {
      const std::string where = Format(match.string(), ":", line.number);
      const auto t = SplitWhitespace(line.text);
      if (t.size() != 2) throw Error(Format(where, ": expected 'depth_path color_path'"));
      entries.push_back(
          {0.0, RequireFile(folder / t[1], match), RequireFile(folder / t[0], match)});
    }
  } else {
    const auto colors = ListImages(color_dir);
    const auto depths = ListImages(folder / "depth");
    if (colors.size() != depths.size()) {
      throw Error(Format(folder.string(), ": ", colors.size(), " colour images but ", depths.size(),
                         " depth images"));
    }
    for (size_t i = 0; i < colors.size(); ++i) entries.push_back({0.0, colors[i], depths[i]});
  }
  if (entries.empty())
    throw Error(Format(folder.string(), ": no frames (empty color/ and depth/)"));
  // Redwood folders carry no time stamps: frame i is at i / 30 s (the sensors' 30 Hz).
  for (size_t i = 0; i < entries.size(); ++i) entries[i].timestamp = i / 30.0;

  Trajectory poses;
  bool by_index = true;
  fs::path poses_file = options.trajectory;
  if (poses_file.empty()) {
    for (const char* name : {"pose.txt", "odometry.log", "trajectory.log"}) {
      if (fs::exists(folder / name, ec)) {
        poses_file = folder / name;
        break;
      }
    }
  }
  if (!poses_file.empty()) {
    poses = ReadPosesFile(poses_file, &by_index);
    if (by_index && poses.size() != entries.size()) {
      throw Error(Format(poses_file.string(), ": ", poses.size(), " poses for ", entries.size(),
                         " frames"));
    }
  }
  // Frame indices are assigned before selection so that poses by index stay with their frames.
  std::vector<FrameEntry> selected = SelectFrames(entries, options, folder.string());
  // Poses by index take their frame's time stamp, so that they pair with the frames (and with the
  // estimated trajectory, for the ATE) by time like any other known poses.
  if (by_index && !poses.empty()) {
    Trajectory kept;
    for (const FrameEntry& e : selected) {
      const double index = std::round(e.timestamp * 30.0);
      kept.Add(e.timestamp, poses.Nearest(index, 0.0)->world_from_camera);
    }
    poses = kept;
  }

  CameraIntrinsics intrinsics;
  if (!options.intrinsics.empty()) {
    intrinsics = ResolveIntrinsics(options.intrinsics);
  } else {
    bool found = false;
    for (const char* name : {"intrinsics.txt", "camera_intrinsic.json", "camera_primesense.json"}) {
      if (fs::exists(folder / name, ec)) {
        intrinsics = ReadIntrinsicsFile(folder / name);
        found = true;
        break;
      }
    }
    if (!found) {
      spdlog::warn(
          "{}: no intrinsics given, assuming the PrimeSense default (525, 525, 319.5, 239.5); give "
          "--intrinsics FILE for this camera's own",
          folder.string());
      intrinsics = *NamedIntrinsics("primesense");
    }
  }
  return std::make_unique<ListedFrameSource>(
      Format("Redwood folder ", folder.string()), std::move(selected), intrinsics,
      MakeEncoding(options, 1000.0), CameraResponse::Parse(options.camera_response),
      std::move(poses), options.max_time_difference, by_index);
}

// The 3x3 camera matrix of a 7-Scenes / 3DMatch camera-intrinsics.txt, for images of the given
// size.
CameraIntrinsics ReadCameraMatrixFile(const fs::path& path, int width, int height) {
  const auto lines = ReadDataLines(path);
  double m[9];
  int n = 0;
  for (const TextLine& line : lines) {
    const std::string where = Format(path.string(), ":", line.number);
    for (const std::string& t : SplitWhitespace(line.text)) {
      if (n == 9) throw Error(Format(where, ": more than the 9 values of a 3x3 camera matrix"));
      m[n++] = ParseDouble(t, where);
    }
  }
  if (n != 9)
    throw Error(Format(path.string(), ": expected a 3x3 camera matrix (9 values), got ", n));
  if (m[1] != 0.0 || m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] != 1.0) {
    throw Error(Format(path.string(), ": not a camera matrix [fx 0 cx; 0 fy cy; 0 0 1]"));
  }
  CameraIntrinsics k;
  k.fx = m[0];
  k.cx = m[2];
  k.fy = m[4];
  k.cy = m[5];
  k.width = width;
  k.height = height;
  k.Validate(path.string());
  return k;
}

// A 7-Scenes / 3DMatch frame pose: a 4x4 camera-to-world matrix in metres.
Eigen::Isometry3d ReadPoseMatrixFile(const fs::path& path) {
  Eigen::Matrix4d m;
  int n = 0;
  for (const TextLine& line : ReadDataLines(path)) {
    const std::string where = Format(path.string(), ":", line.number);
    for (const std::string& t : SplitWhitespace(line.text)) {
      if (n == 16) throw Error(Format(where, ": more than the 16 values of a 4x4 pose"));
      m(n / 4, n % 4) = ParseDouble(t, where);
      ++n;
    }
  }
  if (n != 16)
    throw Error(Format(path.string(), ": expected a 4x4 pose matrix (16 values), got ", n));
  if (!IsValidRigidTransform(m, 1e-3))
    throw Error(Format(path.string(), ": the pose is not a rigid transform"));
  Eigen::Isometry3d pose(m);
  pose.linear() = Eigen::Quaterniond(pose.rotation()).normalized().toRotationMatrix();
  return pose;
}

// True when `dir` holds 7-Scenes / 3DMatch frames (frame-XXXXXX.color.png beside .depth.png).
bool HoldsSevenScenesFrames(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("frame-", 0) == 0 && name.size() > 10 &&
        name.compare(name.size() - 10, 10, ".depth.png") == 0) {
      return true;
    }
  }
  return false;
}

// The native 7-Scenes / 3DMatch layout: frame-XXXXXX.{color,depth}.png (depth in millimetres,
// 0 and 65535 = no data) with optional frame-XXXXXX.pose.txt, camera-intrinsics.txt in the frames'
// folder or the one above. No time stamps: frame i is at i / 30 s.
std::unique_ptr<FrameSource> OpenSevenScenesFolder(const fs::path& folder, const fs::path& frames,
                                                   const SourceOptions& options) {
  std::error_code ec;
  std::vector<fs::path> depths;
  for (const auto& entry : fs::directory_iterator(frames)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("frame-", 0) == 0 && name.size() > 10 &&
        name.compare(name.size() - 10, 10, ".depth.png") == 0) {
      depths.push_back(entry.path());
    }
  }
  std::sort(depths.begin(), depths.end(), NaturalLess);
  std::vector<FrameEntry> entries;
  std::vector<fs::path> pose_files;
  for (const fs::path& depth : depths) {
    const std::string stem =
        depth.filename().string().substr(0, depth.filename().string().size() - 10);
    const fs::path color = frames / (stem + ".color.png");
    if (!fs::is_regular_file(color, ec)) {
      throw Error(
          Format(depth.string(), ": no colour image beside it (", color.filename().string(), ")"));
    }
    entries.push_back({entries.size() / 30.0, color, depth});
    pose_files.push_back(frames / (stem + ".pose.txt"));
  }
  Trajectory poses;
  size_t with_pose = 0;
  for (const fs::path& p : pose_files) with_pose += fs::is_regular_file(p, ec) ? 1 : 0;
  if (!options.trajectory.empty()) {
    bool by_index = false;
    const Trajectory given = ReadPosesFile(options.trajectory, &by_index);
    for (size_t i = 0; i < entries.size(); ++i) {
      const auto p = by_index ? given.Nearest(static_cast<double>(i), 0.0)
                              : given.Nearest(entries[i].timestamp, 0.0);
      if (p) poses.Add(entries[i].timestamp, p->world_from_camera);
    }
  } else if (with_pose == entries.size()) {
    for (size_t i = 0; i < entries.size(); ++i)
      poses.Add(entries[i].timestamp, ReadPoseMatrixFile(pose_files[i]));
  } else if (with_pose > 0) {
    throw Error(Format(frames.string(), ": ", with_pose, " of ", entries.size(),
                       " frames have a .pose.txt; give all or none (or --trajectory FILE)"));
  }
  std::vector<FrameEntry> selected = SelectFrames(entries, options, frames.string());
  if (!poses.empty()) {
    Trajectory kept;
    for (const FrameEntry& e : selected) {
      if (auto p = poses.Nearest(e.timestamp, 0.0)) kept.Add(e.timestamp, p->world_from_camera);
    }
    poses = kept;
  }
  DepthEncoding encoding = MakeEncoding(options, 1000.0);
  encoding.invalid_value = 65535;
  CameraIntrinsics intrinsics;
  if (!options.intrinsics.empty()) {
    intrinsics = ResolveIntrinsics(options.intrinsics);
  } else {
    fs::path file;
    for (const fs::path& dir : {frames, folder, frames.parent_path()}) {
      if (fs::is_regular_file(dir / "camera-intrinsics.txt", ec)) {
        file = dir / "camera-intrinsics.txt";
        break;
      }
    }
    if (file.empty()) {
      throw Error(Format(frames.string(),
                         ": no camera-intrinsics.txt beside the frames or above; give --intrinsics "
                         "FILE or one of ",
                         NamedIntrinsicsList()));
    }
    const ImageDepth first = ReadDepthImage(selected.front().depth, encoding);
    intrinsics = ReadCameraMatrixFile(file, first.width(), first.height());
  }
  spdlog::warn(
      "{}: 7-Scenes layout: colour and depth come from two unregistered cameras; colour is sampled "
      "at "
      "the depth camera's pixels, a few pixels off",
      frames.string());
  return std::make_unique<ListedFrameSource>(Format("7-Scenes folder ", frames.string()),
                                             std::move(selected), intrinsics, encoding,
                                             CameraResponse::Parse(options.camera_response),
                                             std::move(poses), options.max_time_difference, true);
}

// Resamples every frame of a source with lens distortion to the same camera without it.
class UndistortingSource : public FrameSource {
 public:
  explicit UndistortingSource(std::unique_ptr<FrameSource> source)
      : source_(std::move(source)), intrinsics_(source_->Intrinsics()) {
    intrinsics_.distortion = {};
    const CameraIntrinsics& k = source_->Intrinsics();
    const auto& d = k.distortion;
    map_x_.create(k.height, k.width, CV_32F);
    map_y_.create(k.height, k.width, CV_32F);
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        // Where the undistorted pixel (u, v) lies in the distorted image (OpenCV's model).
        const double x = (u - k.cx) / k.fx, y = (v - k.cy) / k.fy;
        const double r2 = x * x + y * y;
        const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
        const double xd = x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
        const double yd = y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
        map_x_.at<float>(v, u) = static_cast<float>(k.fx * xd + k.cx);
        map_y_.at<float>(v, u) = static_cast<float>(k.fy * yd + k.cy);
      }
    }
  }

  std::string Describe() const override { return source_->Describe() + ", undistorted"; }
  std::optional<size_t> FrameCount() const override { return source_->FrameCount(); }
  size_t SkippedFrames() const override { return source_->SkippedFrames(); }
  const CameraIntrinsics& Intrinsics() const override { return intrinsics_; }
  const Trajectory& KnownPoses() const override { return source_->KnownPoses(); }

  std::optional<RgbdFrame> Next() override {
    std::optional<RgbdFrame> frame = source_->Next();
    if (!frame) return frame;
    if (!frame->color.empty())
      frame->color = Remapped(frame->color, frame->color_path, CV_32FC3, cv::INTER_LINEAR);
    // Nearest: a depth between a foreground and a background pixel would be a surface in mid-air.
    if (!frame->depth.empty())
      frame->depth = Remapped(frame->depth, frame->depth_path, CV_32F, cv::INTER_NEAREST);
    frame->intrinsics = intrinsics_;
    return frame;
  }

 private:
  // The image resampled through the undistortion maps (pixels from outside the image: 0).
  template <typename T>
  Image<T> Remapped(const Image<T>& image, const std::string& path, int cv_type,
                    int interpolation) const {
    if (image.width() != map_x_.cols || image.height() != map_x_.rows) {
      throw Error(Format(path, ": image is ", image.width(), "x", image.height(),
                         " but the intrinsics are for ", map_x_.cols, "x", map_x_.rows));
    }
    Image<T> out(image.width(), image.height());
    const cv::Mat in(image.height(), image.width(), cv_type, const_cast<T*>(image.data()));
    cv::Mat dst(out.height(), out.width(), cv_type, out.data());
    cv::remap(in, dst, map_x_, map_y_, interpolation, cv::BORDER_CONSTANT, cv::Scalar::all(0));
    return out;
  }

  std::unique_ptr<FrameSource> source_;
  CameraIntrinsics intrinsics_;
  cv::Mat map_x_, map_y_;
};

std::unique_ptr<FrameSource> OpenFolderSource(const std::string& spec,
                                              const SourceOptions& options);

}  // namespace

std::unique_ptr<FrameSource> Undistorted(std::unique_ptr<FrameSource> source) {
  const auto& d = source->Intrinsics().distortion;
  if (std::all_of(d.begin(), d.end(), [](double c) { return c == 0.0; })) return source;
  return std::make_unique<UndistortingSource>(std::move(source));
}

std::unique_ptr<FrameSource> OpenFrameSource(const std::string& spec,
                                             const SourceOptions& options) {
  return Undistorted(OpenFolderSource(spec, options));
}

namespace {

std::unique_ptr<FrameSource> OpenFolderSource(const std::string& spec,
                                              const SourceOptions& options) {
  options.Validate();
  if (spec.empty()) throw Error("no input given (a TUM or Redwood folder, or a view set)");
  if (spec == "openni2" || spec.rfind("openni2:", 0) == 0 || fs::path(spec).extension() == ".oni") {
    throw Error(Format(spec,
                       ": OpenNI2 cameras and .oni recordings are opened by the capture library "
                       "(genscene::capture::OpenAnySource, capture/openni2_source.h), not by "
                       "core's folder readers"));
  }
  const fs::path folder(spec);
  std::error_code ec;
  if (!fs::exists(folder, ec)) throw Error(Format(spec, ": no such file or folder"));
  if (!fs::is_directory(folder, ec))
    throw Error(Format(spec, ": not a folder (expected a TUM or Redwood folder)"));
  if (fs::exists(folder / "rgb.txt", ec) || !options.associations.empty())
    return OpenTumFolder(folder, options);
  for (const fs::path& frames : {folder, folder / "rgbd-frames"}) {
    if (HoldsSevenScenesFrames(frames)) return OpenSevenScenesFolder(folder, frames, options);
  }
  if (fs::is_directory(folder / "depth", ec)) {
    for (const char* name : {"color", "image", "rgb"}) {
      if (fs::is_directory(folder / name, ec))
        return OpenRedwoodFolder(folder, folder / name, options);
    }
  }
  throw Error(
      Format(spec,
             ": not a recognised sequence (no rgb.txt for TUM, no color/ + depth/ for Redwood, no "
             "frame-XXXXXX.depth.png for 7-Scenes)"));
}

}  // namespace

std::vector<RgbdFrame> ReadAllFrames(FrameSource& source) {
  std::vector<RgbdFrame> frames;
  while (auto frame = source.Next()) frames.push_back(std::move(*frame));
  return frames;
}

}  // namespace genscene
