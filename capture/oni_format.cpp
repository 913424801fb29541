#include "capture/oni_format.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::capture {

namespace fs = std::filesystem;

namespace {

// Record types (OpenNI2 Source/Drivers/OniFile/DataRecords.h).
enum RecordType : uint32_t {
  kNodeAdded_1_0_0_4 = 2,
  kIntProperty = 3,
  kRealProperty = 4,
  kStringProperty = 5,
  kGeneralProperty = 6,
  kNodeRemoved = 7,
  kNodeDataBegin = 8,
  kNodeStateReady = 9,
  kNewData = 10,
  kEnd = 11,
  kNodeAdded_1_0_0_5 = 12,
  kNodeAdded = 13,
  kSeekTable = 14,
};

constexpr char kFileMagic[4] = {'N', 'I', '1', '0'};
constexpr uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
constexpr size_t kFileHeaderSize = 24;         // magic, version (8), max timestamp, max node id
constexpr size_t kRecordHeaderSize = 28;       // 64-bit undo position (file format >= 1.0.1.0)
constexpr size_t kRecordHeaderSizeOld32 = 24;  // 32-bit undo position (older files)
// Offsets inside the file header of the fields patched by Finish().
constexpr uint64_t kMaxTimestampOffset = 12;

// Little-endian field encoder.
class Fields {
 public:
  Fields& U16(uint16_t v) { return Bytes(&v, 2); }
  Fields& U32(uint32_t v) { return Bytes(&v, 4); }
  Fields& U64(uint64_t v) { return Bytes(&v, 8); }
  Fields& F64(double v) { return Bytes(&v, 8); }
  // A string as the container stores it: u32 length including the NUL, then the bytes and NUL.
  Fields& String(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + 1));
    text_.append(s);
    text_.push_back('\0');
    return *this;
  }
  Fields& Bytes(const void* p, size_t n) {
    text_.append(static_cast<const char*>(p), n);  // x86-64 and ARM64 are little-endian
    return *this;
  }
  const std::string& str() const { return text_; }
  size_t size() const { return text_.size(); }

 private:
  std::string text_;
};
static_assert(sizeof(uint32_t) == 4 && sizeof(double) == 8, "the container has fixed-size fields");

// Little-endian field decoder over one record's fields; throws with the record's description.
class FieldReader {
 public:
  FieldReader(const std::string& data, std::string where) : data_(data), where_(std::move(where)) {}
  template <typename T>
  T Get() {
    T v;
    Need(sizeof(T));
    std::memcpy(&v, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string String() {
    const uint32_t n = Get<uint32_t>();
    Need(n);
    std::string s(data_.data() + pos_, n);
    pos_ += n;
    while (!s.empty() && s.back() == '\0') s.pop_back();
    return s;
  }
  std::string Raw(size_t n) {
    Need(n);
    std::string s(data_.data() + pos_, n);
    pos_ += n;
    return s;
  }

 private:
  void Need(size_t n) const {
    if (pos_ + n > data_.size()) {
      throw Error(Format(where_, ": field runs past the record (needs ", n, " bytes at ", pos_,
                         ", record has ", data_.size(), ")"));
    }
  }
  const std::string& data_;
  std::string where_;
  size_t pos_ = 0;
};

std::string CodecText(uint32_t codec) {
  std::string s(reinterpret_cast<const char*>(&codec), 4);
  for (char& c : s) {
    if (c < 32 || c > 126) c = '?';
  }
  return s;
}

uint32_t CodecId(const char (&text)[5]) {
  uint32_t id;
  std::memcpy(&id, text, 4);
  return id;
}

}  // namespace

// --- Writer -------------------------------------------------------------------------------------

void OniLayout::Validate() const {
  if (width < 1 || height < 1 || width > 1600 || height > 1200) {
    // OpenNI2's player holds one frame in a buffer of 1600 x 1200 x 3 bytes.
    throw Error(Format("oni: frame size ", width, "x", height, " is not in 1x1 .. 1600x1200"));
  }
  if (fps < 1 || fps > 1000) throw Error(Format("oni: fps ", fps, " is not in [1, 1000]"));
  intrinsics.Validate("oni: intrinsics");
  if (intrinsics.width != width || intrinsics.height != height) {
    throw Error(Format("oni: frames ", width, "x", height, " but intrinsics say ", intrinsics.width,
                       "x", intrinsics.height));
  }
}

OniWriter::OniWriter(const fs::path& path, const OniLayout& layout) : path_(path), layout_(layout) {
  layout_.Validate();
  out_.open(path, std::ios::binary | std::ios::trunc);
  if (!out_) throw Error(Format(path.string(), ": cannot write (", std::strerror(errno), ")"));
  WriteHeaderRecords();
}

OniWriter::~OniWriter() = default;

void OniWriter::Check(const char* what) {
  if (!out_) throw Error(Format(path_.string(), ": writing ", what, " failed (disk full?)"));
}

void OniWriter::WriteRecord(uint32_t type, uint32_t node, const std::string& fields,
                            const void* payload, uint32_t payload_size, uint64_t undo) {
  Fields header;
  header.U32(kRecordMagic)
      .U32(type)
      .U32(node)
      .U32(static_cast<uint32_t>(kRecordHeaderSize + fields.size()));
  header.U32(payload_size).U64(undo);
  out_.write(header.str().data(), static_cast<std::streamsize>(header.size()));
  out_.write(fields.data(), static_cast<std::streamsize>(fields.size()));
  if (payload_size > 0) out_.write(static_cast<const char*>(payload), payload_size);
  Check("a record");
}

void OniWriter::WriteHeaderRecords() {
  const int num_nodes = layout_.with_color ? 2 : 1;
  Fields file_header;
  file_header.Bytes(kFileMagic, 4);
  file_header.Bytes("\x01\x00", 2).U16(1).U32(0);  // version 1.0.1.0: 64-bit file offsets
  file_header.U64(0);                              // max timestamp, patched by Finish()
  file_header.U32(num_nodes - 1);                  // max node id
  out_.write(file_header.str().data(), static_cast<std::streamsize>(file_header.size()));

  const CameraIntrinsics& k = layout_.intrinsics;
  const double hfov = 2.0 * std::atan(layout_.width / (2.0 * k.fx));
  const double vfov = 2.0 * std::atan(layout_.height / (2.0 * k.fy));
  const uint64_t pixels = static_cast<uint64_t>(layout_.width) * layout_.height;
  nodes_.resize(num_nodes);
  for (int node = 0; node < num_nodes; ++node) {
    const bool depth = node == 0;
    const auto int_property = [&](const std::string& name, uint64_t value) {
      Fields f;
      f.String(name).U32(8).U64(value);
      WriteRecord(kIntProperty, node, f.str(), nullptr, 0, 0);
    };
    const auto general_property = [&](const std::string& name, const Fields& value) {
      Fields f;
      f.String(name)
          .U32(static_cast<uint32_t>(value.size()))
          .Bytes(value.str().data(), value.size());
      WriteRecord(kGeneralProperty, node, f.str(), nullptr, 0, 0);
    };
    // NodeAdded: name, type, codec, frame count, min/max timestamp, seek table position. The
    // counts and time stamps are patched by Finish().
    nodes_[node].node_added = static_cast<uint64_t>(out_.tellp());
    Fields added;
    added.String(depth ? "Depth" : "Image")
        .U32(depth ? kOniNodeDepth : kOniNodeImage)
        .U32(CodecId("NONE"));
    added.U32(0).U64(0).U64(0).U64(0);
    WriteRecord(kNodeAdded, node, added.str(), nullptr, 0, 0);

    // The properties OpenNI2's player turns into the stream's video mode, frame size, cropping and
    // field of view (PlayerDevice::OnNodeIntPropChanged / OnNodeGeneralPropChanged).
    int_property("oniRequiredFrameSize", pixels * (depth ? 2 : 3));
    general_property("xnMapOutputMode",
                     Fields().U32(layout_.width).U32(layout_.height).U32(layout_.fps));
    int_property("oniPixelFormat", depth ? kOniPixelDepth1Mm : kOniPixelRgb888);
    if (layout_.write_cropping) {
      // XnCropping: u32 enabled, u16 x offset, y offset, width, height: all zero = not cropped.
      general_property("xnCropping", Fields().U32(0).U16(0).U16(0).U16(0).U16(0));
    }
    general_property("xnFOV", Fields().F64(hfov).F64(vfov));
    int_property("xnMirror", layout_.mirrored ? 1 : 0);
    if (depth) int_property("xnDeviceMaxDepth", 10000);
    general_property("gsIntrinsics", Fields().F64(k.fx).F64(k.fy).F64(k.cx).F64(k.cy));
    WriteRecord(kNodeStateReady, node, "", nullptr, 0, 0);
  }
  // DataBegin: frame count and max timestamp, patched by Finish(). The player stops reading the
  // header at the first one.
  for (int node = 0; node < num_nodes; ++node) {
    nodes_[node].data_begin = static_cast<uint64_t>(out_.tellp());
    WriteRecord(kNodeDataBegin, node, Fields().U32(0).U64(0).str(), nullptr, 0, 0);
  }
}

void OniWriter::Add(const OniRawFrame& frame) {
  GS_CHECK(!finished_);
  const size_t pixels = static_cast<size_t>(layout_.width) * layout_.height;
  const std::string where = Format(path_.string(), ": frame ", frames_ + 1);
  if (frame.depth_mm.size() != pixels) {
    throw Error(Format(where, ": depth has ", frame.depth_mm.size(), " pixels, the recording is ",
                       layout_.width, "x", layout_.height));
  }
  if (layout_.with_color != !frame.color_rgb.empty() ||
      (layout_.with_color && frame.color_rgb.size() != 3 * pixels)) {
    throw Error(Format(where, ": colour has ", frame.color_rgb.size() / 3,
                       " pixels, the recording is ",
                       layout_.with_color ? Format(layout_.width, "x", layout_.height)
                                          : std::string("depth-only")));
  }
  if (frames_ > 0 && frame.timestamp_us < max_timestamp_) {
    throw Error(Format(where, ": time stamp ", frame.timestamp_us,
                       " us is before the previous frame's ", max_timestamp_, " us"));
  }
  const uint32_t frame_number = static_cast<uint32_t>(frames_ + 1);  // the container counts from 1
  const Fields fields = Fields().U64(frame.timestamp_us).U32(frame_number);
  // A mirrored recording stores each row reversed, as a mirroring device delivers it.
  std::vector<uint16_t> depth_flipped;
  std::vector<uint8_t> color_flipped;
  const uint16_t* depth = frame.depth_mm.data();
  const uint8_t* color = frame.color_rgb.data();
  if (layout_.mirrored) {
    depth_flipped = frame.depth_mm;
    color_flipped = frame.color_rgb;
    const size_t w = static_cast<size_t>(layout_.width);
    for (size_t row = 0; row < pixels; row += w) {
      for (size_t u = 0; u < w; ++u) {
        depth_flipped[row + u] = frame.depth_mm[row + w - 1 - u];
        for (size_t c = 0; c < 3 && !color_flipped.empty(); ++c) {
          color_flipped[3 * (row + u) + c] = frame.color_rgb[3 * (row + w - 1 - u) + c];
        }
      }
    }
    depth = depth_flipped.data();
    color = color_flipped.data();
  }
  for (size_t node = 0; node < nodes_.size(); ++node) {
    const uint64_t offset = static_cast<uint64_t>(out_.tellp());
    if (node == 0) {
      WriteRecord(kNewData, 0, fields.str(), depth,
                  static_cast<uint32_t>(pixels * sizeof(uint16_t)), nodes_[0].last_data);
    } else {
      WriteRecord(kNewData, 1, fields.str(), color, static_cast<uint32_t>(3 * pixels),
                  nodes_[1].last_data);
    }
    nodes_[node].last_data = offset;
  }
  if (frames_ == 0) min_timestamp_ = frame.timestamp_us;
  max_timestamp_ = frame.timestamp_us;
  ++frames_;
}

void OniWriter::Finish() {
  GS_CHECK(!finished_);
  if (frames_ == 0) throw Error(Format(path_.string(), ": no frames to write"));
  WriteRecord(kEnd, 0, "", nullptr, 0, 0);
  // Patch the counts and time stamps now known.
  const auto patch = [&](uint64_t offset, const Fields& f) {
    out_.seekp(static_cast<std::streamoff>(offset));
    out_.write(f.str().data(), static_cast<std::streamsize>(f.size()));
  };
  patch(kMaxTimestampOffset, Fields().U64(max_timestamp_));
  const uint32_t count = static_cast<uint32_t>(frames_);
  for (size_t node = 0; node < nodes_.size(); ++node) {
    const size_t name_size = 4 + std::strlen(node == 0 ? "Depth" : "Image") + 1;
    patch(nodes_[node].node_added + kRecordHeaderSize + name_size + 8,
          Fields().U32(count).U64(min_timestamp_).U64(max_timestamp_));
    patch(nodes_[node].data_begin + kRecordHeaderSize, Fields().U32(count).U64(max_timestamp_));
  }
  out_.close();
  Check("the end of the file");
  finished_ = true;
}

void WriteOniFile(const fs::path& path, const OniLayout& layout,
                  const std::vector<OniRawFrame>& frames) {
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    OniWriter writer(tmp, layout);
    for (const OniRawFrame& f : frames) writer.Add(f);
    writer.Finish();
  });
}

// --- Reader -------------------------------------------------------------------------------------

std::string OniNodeInfo::TypeName() const {
  switch (type) {
    case kOniNodeDepth:
      return "depth";
    case kOniNodeImage:
      return "colour";
    case kOniNodeIr:
      return "IR";
    default:
      return Format("type ", type);
  }
}

const OniNodeInfo* OniFileInfo::FindNode(uint32_t type) const {
  for (const OniNodeInfo& n : nodes) {
    if (n.type == type) return &n;
  }
  return nullptr;
}

namespace {

// Called for each NewData record with the stream positioned at its payload.
using NewDataVisitor = std::function<void(OniNodeInfo& node, uint64_t timestamp_us, uint32_t frame,
                                          uint32_t payload_size, std::istream& in)>;

void ApplyProperty(OniNodeInfo& node, uint32_t type, FieldReader& r) {
  const std::string name = r.String();
  const uint32_t size = r.Get<uint32_t>();
  const std::string value = r.Raw(size);
  const auto u32_at = [&](size_t i) {
    uint32_t v;
    std::memcpy(&v, value.data() + 4 * i, 4);
    return v;
  };
  const auto f64_at = [&](size_t i) {
    double v;
    std::memcpy(&v, value.data() + 8 * i, 8);
    return v;
  };
  if (type == kIntProperty && size == 8) {
    uint64_t v;
    std::memcpy(&v, value.data(), 8);
    if (name == "oniPixelFormat") node.pixel_format = static_cast<uint32_t>(v);
    if (name == "oniRequiredFrameSize" || name == "RequiredDataSize") node.required_frame_size = v;
    if (name == "xnMirror") node.mirrored = v != 0;
  } else if (type == kGeneralProperty) {
    if (name == "xnMapOutputMode" && size == 12)
      node.map_output_mode = std::array<uint32_t, 3>{u32_at(0), u32_at(1), u32_at(2)};
    if (name == "xnCropping") node.has_cropping = true;
    if (name == "xnFOV" && size == 16)
      node.field_of_view = std::array<double, 2>{f64_at(0), f64_at(1)};
    if (name == "gsIntrinsics" && size == 32)
      node.gs_intrinsics = std::array<double, 4>{f64_at(0), f64_at(1), f64_at(2), f64_at(3)};
  }
}

OniFileInfo WalkOniFile(const fs::path& path, const NewDataVisitor& on_data) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw Error(Format(name, ": no such file"));
  const uint64_t file_size = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Format(name, ": cannot open (", std::strerror(errno), ")"));

  // File header.
  std::string header(kFileHeaderSize, '\0');
  in.read(header.data(), kFileHeaderSize);
  if (in.gcount() < 4 || std::memcmp(header.data(), kFileMagic, 4) != 0) {
    throw Error(Format(name, ": not an OpenNI .oni recording (it does not start with \"NI10\")"));
  }
  if (static_cast<size_t>(in.gcount()) < kFileHeaderSize) {
    throw Error(Format(name, ": truncated: ", file_size, " bytes, shorter than the ",
                       kFileHeaderSize, "-byte file header"));
  }
  OniFileInfo info;
  info.path = path;
  FieldReader hr(header, name + ": file header");
  hr.Raw(4);
  info.version = {hr.Get<uint8_t>(), hr.Get<uint8_t>(), hr.Get<uint16_t>(),
                  static_cast<int>(hr.Get<uint32_t>())};
  info.max_timestamp_us = hr.Get<uint64_t>();
  info.max_node_id = hr.Get<uint32_t>();
  if (info.version[0] != 1 || info.version[1] != 0 ||
      (info.version[2] == 0 && info.version[3] < 4) || info.version[2] > 1) {
    throw Error(Format(name, ": .oni format version ", info.version[0], ".", info.version[1], ".",
                       info.version[2], ".", info.version[3],
                       " is not one OpenNI2 plays (1.0.0.4 .. 1.0.1.0)"));
  }
  if (info.max_node_id > 1000)
    throw Error(Format(name, ": header says ", info.max_node_id + 1, " nodes (corrupt header)"));
  const bool old32 = info.version[2] == 0;  // before 1.0.1.0: 32-bit undo positions
  const size_t record_header_size = old32 ? kRecordHeaderSizeOld32 : kRecordHeaderSize;

  std::vector<int> node_index(info.max_node_id + 1, -1);  // node id -> index in info.nodes
  uint64_t pos = kFileHeaderSize;
  for (size_t record = 1; pos < file_size; ++record) {
    const std::string at = Format(name, ": record ", record, " at byte ", pos);
    if (file_size - pos < record_header_size) {
      throw Error(Format(name, ": truncated: the file ends ", file_size - pos,
                         " bytes into the header of record ", record, " (at byte ", pos,
                         "; the recording was cut short)"));
    }
    std::string rh(record_header_size, '\0');
    in.seekg(static_cast<std::streamoff>(pos));
    in.read(rh.data(), static_cast<std::streamsize>(record_header_size));
    FieldReader h(rh, at);
    const uint32_t magic = h.Get<uint32_t>(), type = h.Get<uint32_t>(), node_id = h.Get<uint32_t>();
    const uint32_t fields_size = h.Get<uint32_t>(), payload_size = h.Get<uint32_t>();
    if (magic != kRecordMagic) throw Error(Format(at, ": no record marker \"NIR\" (corrupt file)"));
    if (fields_size < record_header_size)
      throw Error(
          Format(at, ": fields size ", fields_size, " is below the header size (corrupt file)"));
    const uint64_t record_end = pos + fields_size + static_cast<uint64_t>(payload_size);
    if (record_end > file_size) {
      throw Error(Format(name, ": truncated: record ", record, " (type ", type, ") at byte ", pos,
                         " needs ", record_end - pos, " bytes but the file ends after ",
                         file_size - pos, " (the recording was cut short)"));
    }
    std::string fields(fields_size - record_header_size, '\0');
    in.read(fields.data(), static_cast<std::streamsize>(fields.size()));
    FieldReader r(fields, at);
    const auto node = [&]() -> OniNodeInfo& {
      if (node_id >= node_index.size() || node_index[node_id] < 0) {
        throw Error(
            Format(at, ": refers to node ", node_id, " which was never added (corrupt file)"));
      }
      return info.nodes[node_index[node_id]];
    };
    switch (type) {
      case kNodeAdded:
      case kNodeAdded_1_0_0_5:
      case kNodeAdded_1_0_0_4: {
        if (node_id >= node_index.size()) {
          throw Error(Format(at, ": node id ", node_id, " above the header's maximum ",
                             info.max_node_id, " (corrupt file)"));
        }
        OniNodeInfo n;
        n.id = node_id;
        n.name = r.String();
        n.type = r.Get<uint32_t>();
        n.codec = CodecText(r.Get<uint32_t>());
        if (type != kNodeAdded_1_0_0_4) {
          n.frames = r.Get<uint32_t>();
          n.min_timestamp_us = r.Get<uint64_t>();
          n.max_timestamp_us = r.Get<uint64_t>();
        }
        if (node_index[node_id] >= 0) {
          info.nodes[node_index[node_id]] = n;  // re-added after a removal
        } else {
          node_index[node_id] = static_cast<int>(info.nodes.size());
          info.nodes.push_back(n);
        }
        break;
      }
      case kIntProperty:
      case kGeneralProperty:
        ApplyProperty(node(), type, r);
        break;
      case kNewData: {
        OniNodeInfo& n = node();
        const uint64_t timestamp = r.Get<uint64_t>();
        const uint32_t frame = r.Get<uint32_t>();
        ++n.data_records;
        if (on_data) {
          in.seekg(static_cast<std::streamoff>(pos + fields_size));
          on_data(n, timestamp, frame, payload_size, in);
        }
        break;
      }
      case kEnd:
        info.has_end_record = true;
        break;
      case kRealProperty:
      case kStringProperty:
      case kNodeRemoved:
      case kNodeDataBegin:
      case kNodeStateReady:
      case kSeekTable:
        break;
      default:
        throw Error(Format(at, ": unknown record type ", type, " (corrupt file)"));
    }
    pos = record_end;
  }
  if (!info.has_end_record) {
    throw Error(Format(name, ": truncated: ", file_size,
                       " bytes without the end record (the recording was cut short)"));
  }
  for (const OniNodeInfo& n : info.nodes) {
    const bool generator =
        n.type == kOniNodeDepth || n.type == kOniNodeImage || n.type == kOniNodeIr;
    if (generator && n.frames != n.data_records) {
      throw Error(Format(name, ": ", n.TypeName(), " stream '", n.name, "' declares ", n.frames,
                         " frames but holds ", n.data_records, " (corrupt file)"));
    }
  }
  return info;
}

}  // namespace

OniFileInfo InspectOniFile(const fs::path& path) {
  return WalkOniFile(path, nullptr);
}

void RequirePlayableRgbd(const OniFileInfo& info) {
  const std::string name = info.path.string();
  const OniNodeInfo* depth = info.FindNode(kOniNodeDepth);
  const OniNodeInfo* color = info.FindNode(kOniNodeImage);
  if (!depth && !color) throw Error(Format(name, ": holds neither a depth nor a colour stream"));
  if (!depth)
    throw Error(
        Format(name, ": has a colour stream but no depth stream (genscene needs depth + colour)"));
  if (!color)
    throw Error(
        Format(name, ": has a depth stream but no colour stream (genscene needs depth + colour)"));
  for (const OniNodeInfo* n : {depth, color}) {
    const std::string stream = Format(name, ": ", n->TypeName(), " stream '", n->name, "'");
    if (!n->has_cropping) {
      throw Error(Format(
          stream,
          " has no xnCropping property; OpenNI2's player plays no frames from such a stream"));
    }
    if (!n->map_output_mode)
      throw Error(Format(stream, " has no xnMapOutputMode property (frame size unknown)"));
    if (n->frames == 0) throw Error(Format(stream, " has no frames"));
  }
}

OniRecording ReadOniFile(const fs::path& path) {
  OniRecording rec;
  const OniFileInfo header = InspectOniFile(path);
  RequirePlayableRgbd(header);
  const OniNodeInfo& depth = *header.FindNode(kOniNodeDepth);
  const OniNodeInfo& color = *header.FindNode(kOniNodeImage);
  const std::string name = path.string();
  for (const OniNodeInfo* n : {&depth, &color}) {
    if (n->codec != "NONE") {
      throw Error(Format(name, ": ", n->TypeName(), " stream is compressed with codec '", n->codec,
                         "'; genscene's own reader decodes only uncompressed ('NONE') recordings "
                         "(OpenNI2 plays the others)"));
    }
  }
  rec.width = static_cast<int>((*depth.map_output_mode)[0]);
  rec.height = static_cast<int>((*depth.map_output_mode)[1]);
  if ((*color.map_output_mode)[0] != (*depth.map_output_mode)[0] ||
      (*color.map_output_mode)[1] != (*depth.map_output_mode)[1]) {
    throw Error(Format(name, ": depth ", rec.width, "x", rec.height, " but colour ",
                       (*color.map_output_mode)[0], "x", (*color.map_output_mode)[1]));
  }
  if (depth.pixel_format.value_or(kOniPixelDepth1Mm) != kOniPixelDepth1Mm ||
      color.pixel_format.value_or(kOniPixelRgb888) != kOniPixelRgb888) {
    throw Error(
        Format(name, ": pixel formats ", depth.pixel_format.value_or(0), " / ",
               color.pixel_format.value_or(0),
               "; genscene's own reader takes depth 100 (DEPTH_1_MM) and colour 200 (RGB888)"));
  }
  const size_t pixels = static_cast<size_t>(rec.width) * rec.height;
  rec.frames.resize(depth.frames);
  std::vector<bool> seen_color(depth.frames, false);
  rec.info = WalkOniFile(path, [&](OniNodeInfo& n, uint64_t timestamp, uint32_t frame,
                                   uint32_t size, std::istream& in) {
    const bool is_depth = n.id == depth.id;
    if (!is_depth && n.id != color.id) return;
    if (frame < 1 || frame > rec.frames.size()) {
      throw Error(Format(name, ": ", n.TypeName(), " frame number ", frame, " outside 1..",
                         rec.frames.size()));
    }
    const size_t expected = pixels * (is_depth ? 2 : 3);
    if (size != expected) {
      throw Error(Format(name, ": ", n.TypeName(), " frame ", frame, " has ", size,
                         " bytes, expected ", expected));
    }
    OniRawFrame& f = rec.frames[frame - 1];
    if (is_depth) {
      f.timestamp_us = timestamp;
      f.depth_mm.resize(pixels);
      in.read(reinterpret_cast<char*>(f.depth_mm.data()), static_cast<std::streamsize>(size));
    } else {
      seen_color[frame - 1] = true;
      f.color_rgb.resize(3 * pixels);
      in.read(reinterpret_cast<char*>(f.color_rgb.data()), static_cast<std::streamsize>(size));
    }
    if (!in) throw Error(Format(name, ": cannot read ", n.TypeName(), " frame ", frame));
  });
  for (size_t i = 0; i < rec.frames.size(); ++i) {
    if (rec.frames[i].depth_mm.empty() || !seen_color[i]) {
      throw Error(Format(name, ": frame ", i + 1, " lacks its ",
                         rec.frames[i].depth_mm.empty() ? "depth" : "colour"));
    }
  }
  return rec;
}

// --- Conversions --------------------------------------------------------------------------------

OniRawFrame ToOniRawFrame(const RgbdFrame& frame, const CameraResponse& response) {
  OniRawFrame raw;
  if (!(frame.timestamp >= 0.0) || frame.timestamp > 1.8e13) {
    throw Error(
        Format("frame at t = ", frame.timestamp, " s: a .oni time stamp must be in [0, 1.8e13] s"));
  }
  raw.timestamp_us = static_cast<uint64_t>(std::llround(frame.timestamp * 1e6));
  if (frame.depth.empty())
    throw Error(Format("frame at t = ", frame.timestamp, " s has no depth; a .oni frame needs it"));
  raw.depth_mm.resize(frame.depth.size());
  for (size_t i = 0; i < frame.depth.size(); ++i) {
    const double mm = std::round(static_cast<double>(frame.depth.pixels()[i]) * 1000.0);
    if (!(mm >= 0.0 && mm <= 65535.0)) {
      throw Error(Format("frame at t = ", frame.timestamp, " s: depth ", frame.depth.pixels()[i],
                         " m at pixel (", i % frame.depth.width(), ", ", i / frame.depth.width(),
                         ") does not fit in 16-bit millimetres (0 .. 65.535 m)"));
    }
    raw.depth_mm[i] = static_cast<uint16_t>(mm);
  }
  if (!frame.color.empty()) {
    raw.color_rgb.resize(3 * frame.color.size());
    for (size_t i = 0; i < frame.color.size(); ++i) {
      for (int c = 0; c < 3; ++c) {
        const float encoded = response.FromLinear(frame.color.pixels()[i][c]);
        raw.color_rgb[3 * i + c] =
            static_cast<uint8_t>(std::lround(std::clamp(encoded, 0.0f, 1.0f) * 255.0f));
      }
    }
  }
  return raw;
}

CameraIntrinsics IntrinsicsFromFieldOfView(double hfov_rad, double vfov_rad, int width,
                                           int height) {
  if (!(hfov_rad > 0.0 && hfov_rad < M_PI && vfov_rad > 0.0 && vfov_rad < M_PI)) {
    throw Error(Format("field of view ", hfov_rad, " x ", vfov_rad,
                       " rad is not in (0, pi); give --intrinsics"));
  }
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (2.0 * std::tan(hfov_rad / 2.0));
  k.fy = height / (2.0 * std::tan(vfov_rad / 2.0));
  k.cx = 0.5 * (width - 1);
  k.cy = 0.5 * (height - 1);
  return k;
}

}  // namespace genscene::capture
