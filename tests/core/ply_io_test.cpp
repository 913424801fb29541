#include "core/ply_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/check.h"
#include "core/color.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

using test::ErrorOf;

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class PlyIoTest : public ::testing::Test {
 protected:
  fs::path Path(const std::string& name) const { return dir_ / name; }
  fs::path WriteText(const std::string& name, const std::string& text) const {
    std::ofstream(Path(name), std::ios::binary) << text;
    return Path(name);
  }

  test::TempDir temp_;
  const fs::path& dir_ = temp_.path();
};

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Two tetrahedra sharing vertex 0 (non-manifold at a vertex), with normals, vertex colours and
// face colours that are not on the 8-bit grid.
TriangleMesh TestMesh() {
  TriangleMesh mesh;
  mesh.vertices = {{0.0f, 0.0f, 0.0f},
                   {1.0f, 0.0f, 0.0f},
                   {0.0f, 1.0f, 0.0f},
                   {0.0f, 0.0f, 1.0f},
                   {-1.0f, 0.0f, 0.0f},
                   {0.0f, -1.0f, 0.0f},
                   {0.123456789f, -2.5e-7f, 1234.5678f}};
  mesh.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3},
                {0, 5, 4}, {0, 4, 6}, {0, 6, 5}, {4, 5, 6}};
  mesh.ComputeVertexNormals();
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    mesh.vertex_colors.emplace_back(0.1f * static_cast<float>(i) + 0.013f, 0.5f,
                                    1.0f - 0.09f * static_cast<float>(i));
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    mesh.face_colors.emplace_back(0.123456f + 0.1f * static_cast<float>(f), 0.0f, 0.987654f);
  }
  mesh.Validate("TestMesh");
  return mesh;
}

void ExpectSameMesh(const TriangleMesh& written, const TriangleMesh& read) {
  ASSERT_EQ(read.vertices.size(), written.vertices.size());
  ASSERT_EQ(read.faces.size(), written.faces.size());
  for (size_t i = 0; i < written.vertices.size(); ++i) {
    EXPECT_EQ(read.vertices[i], written.vertices[i]) << "vertex " << i;  // exact
  }
  for (size_t f = 0; f < written.faces.size(); ++f)
    EXPECT_EQ(read.faces[f], written.faces[f]) << "face " << f;
  ASSERT_EQ(read.normals.size(), written.normals.size());
  for (size_t i = 0; i < written.normals.size(); ++i) {
    EXPECT_EQ(read.normals[i], written.normals[i]) << "normal " << i;
  }
  // Vertex colours are stored as float albedo_r/g/b too, preferred on read: exact.
  ASSERT_EQ(read.vertex_colors.size(), written.vertex_colors.size());
  for (size_t i = 0; i < written.vertex_colors.size(); ++i) {
    EXPECT_EQ(read.vertex_colors[i], written.vertex_colors[i]) << "vertex colour " << i;
  }
  // Face colours are stored as float albedo_r/g/b, which are preferred on read: exact.
  ASSERT_EQ(read.face_colors.size(), written.face_colors.size());
  for (size_t f = 0; f < written.face_colors.size(); ++f) {
    EXPECT_EQ(read.face_colors[f], written.face_colors[f]) << "face colour " << f;
  }
}

// Observed colours are named color_r/g/b (not albedo), in binary and ASCII, and read back exactly.
TEST_F(PlyIoTest, ObservedColoursAreNamedForWhatTheyHold) {
  const TriangleMesh mesh = TestMesh();
  for (bool binary : {true, false}) {
    const fs::path path = Path(binary ? "observed.ply" : "observed_ascii.ply");
    WritePly(path, mesh, {binary, PlyColors::kObserved});
    const std::string text = ReadAll(path);
    EXPECT_NE(text.find("property float color_r\n"), std::string::npos);
    EXPECT_EQ(text.find("albedo_r"), std::string::npos);
    ExpectSameMesh(mesh, ReadPly(path));
  }
}

TEST_F(PlyIoTest, RoundTripBinary) {
  const TriangleMesh mesh = TestMesh();
  const fs::path path = Path("mesh.ply");
  WritePly(path, mesh);
  const std::string text = ReadAll(path);
  EXPECT_NE(text.find("format binary_little_endian 1.0\n"), std::string::npos);
  EXPECT_NE(text.find("property float albedo_r\n"), std::string::npos);
  EXPECT_NE(text.find("property uchar red\n"), std::string::npos);
  ExpectSameMesh(mesh, ReadPly(path));
}

TEST_F(PlyIoTest, RoundTripAscii) {
  const TriangleMesh mesh = TestMesh();
  const fs::path path = Path("mesh.ply");
  PlyWriteOptions options;
  options.binary = false;
  WritePly(path, mesh, options);
  EXPECT_EQ(ReadAll(path).rfind("ply\nformat ascii 1.0\n", 0), 0u);
  ExpectSameMesh(mesh, ReadPly(path));
}

TEST_F(PlyIoTest, RoundTripPositionsOnlyAndFaceColoursAlsoAsSrgbBytes) {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.faces = {{0, 1, 2}};
  mesh.face_colors = {{0.5f, 0.25f, 1.0f}};
  const fs::path path = Path("plain.ply");
  WritePly(path, mesh);
  const TriangleMesh read = ReadPly(path);
  EXPECT_TRUE(read.normals.empty());
  EXPECT_TRUE(read.vertex_colors.empty());
  EXPECT_EQ(read.face_colors, mesh.face_colors);

  // The uchar copy of the face colour is the sRGB encoding of the linear value.
  const std::string text = ReadAll(path);
  const size_t data = text.find("end_header\n") + 11;
  const size_t face = data + 3 * 12 + 1 + 3 * 4;  // 3 vertices, list length, 3 indices
  ASSERT_GE(text.size(), face + 3 + 12);
  EXPECT_EQ(static_cast<unsigned char>(text[face]), std::lround(LinearToSrgb(0.5f) * 255.0f));
  EXPECT_EQ(static_cast<unsigned char>(text[face + 1]), std::lround(LinearToSrgb(0.25f) * 255.0f));
  EXPECT_EQ(static_cast<unsigned char>(text[face + 2]), 255);
}

TEST_F(PlyIoTest, AtomicWriteLeavesNoTemporaryFile) {
  const fs::path path = Path("mesh.ply");
  WritePly(path, TestMesh());
  WritePly(path, TestMesh());  // overwrite
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    ++files;
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path();
  }
  EXPECT_EQ(files, 1);
}

TEST_F(PlyIoTest, HighDynamicRangeVertexColoursRoundTrip) {
  TriangleMesh mesh = TestMesh();
  mesh.vertex_colors[3] = {2.0f, 0.0f, 0.5f};  // above 1: exact in the floats, clamped in the bytes
  WritePly(Path("hdr.ply"), mesh);
  EXPECT_EQ(ReadPly(Path("hdr.ply")).vertex_colors[3], mesh.vertex_colors[3]);
}

TEST_F(PlyIoTest, FailedWriteLeavesNoFile) {
  TriangleMesh mesh = TestMesh();
  mesh.vertex_colors[3] = {NAN, 0.0f, 0.0f};  // cannot be stored
  const fs::path path = Path("mesh.ply");
  const std::string message = ErrorOf([&] { WritePly(path, mesh); });
  EXPECT_NE(message.find(path.string()), std::string::npos) << message;
  EXPECT_NE(message.find("vertex colour 3"), std::string::npos) << message;
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(PlyIoTest, TruncatedBinaryFileIsAnError) {
  const fs::path path = Path("mesh.ply");
  WritePly(path, TestMesh());
  const uintmax_t size = fs::file_size(path);
  for (const uintmax_t cut : {uintmax_t{1}, uintmax_t{5}, size / 2}) {
    WritePly(path, TestMesh());
    fs::resize_file(path, size - cut);
    const std::string message = ErrorOf([&] { ReadPly(path); });
    EXPECT_NE(message.find(path.string()), std::string::npos) << "cut " << cut << ": " << message;
  }
}

TEST_F(PlyIoTest, TruncatedAsciiFileIsAnError) {
  const fs::path path = Path("mesh.ply");
  PlyWriteOptions ascii;
  ascii.binary = false;
  WritePly(path, TestMesh(), ascii);
  const std::string text = ReadAll(path);
  // Cut inside the last face line (its colour values missing) and inside the vertices.
  for (const size_t keep : {text.size() - 12, text.find("end_header") + 40}) {
    WriteText("mesh.ply", text.substr(0, keep));
    const std::string message = ErrorOf([&] { ReadPly(path); });
    EXPECT_NE(message.find(path.string()), std::string::npos) << "keep " << keep << ": " << message;
  }
}

TEST_F(PlyIoTest, HeaderClaimingBillionVerticesIsAnErrorWithoutAllocating) {
  const std::string header_end =
      "property float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const fs::path binary =
      WriteText("binary.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\n" +
                                  header_end + std::string(48, '\0'));
  const std::string message = ErrorOf([&] { ReadPly(binary); });
  EXPECT_NE(message.find(binary.string()), std::string::npos) << message;
  EXPECT_NE(message.find("1000000000"), std::string::npos) << message;

  const fs::path ascii =
      WriteText("ascii.ply", "ply\nformat ascii 1.0\nelement vertex 1000000000\n" + header_end +
                                 "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const std::string ascii_message = ErrorOf([&] { ReadPly(ascii); });
  EXPECT_NE(ascii_message.find(ascii.string()), std::string::npos) << ascii_message;
}

TEST_F(PlyIoTest, NotAPlyIsAnError) {
  const fs::path path = WriteText("mesh.ply", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const std::string message = ErrorOf([&] { ReadPly(path); });
  EXPECT_NE(message.find(path.string()), std::string::npos) << message;
  EXPECT_NE(message.find("not a PLY"), std::string::npos) << message;
}

TEST_F(PlyIoTest, MissingAndEmptyFilesAreErrors) {
  const fs::path missing = Path("missing.ply");
  const std::string message = ErrorOf([&] { ReadPly(missing); });
  EXPECT_NE(message.find(missing.string()), std::string::npos) << message;
  EXPECT_NE(message.find("not found"), std::string::npos) << message;

  const fs::path empty = WriteText("empty.ply", "");
  const std::string empty_message = ErrorOf([&] { ReadPly(empty); });
  EXPECT_NE(empty_message.find(empty.string()), std::string::npos) << empty_message;
}

TEST_F(PlyIoTest, MalformedHeadersAreErrors) {
  const std::string vertex =
      "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
  const struct {
    const char* name;
    std::string text;
    const char* expected;
  } cases[] = {
      // The header ends with the file: an Error, not a read past it.
      {"no_end.ply", "ply\nformat ascii 1.0\n" + vertex, "end_header"},
      {"big_endian.ply",
       "ply\nformat binary_big_endian 1.0\n" + vertex + "end_header\n" + std::string(12, '\0'),
       "binary_big_endian"},
      {"no_format.ply", "ply\n" + vertex + "end_header\n0 0 0\n", "format"},
      {"bad_count.ply", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", "-3"},
      {"bad_type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty real x\nend_header\n",
       "real"},
      {"no_xyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
       "x/y/z"},
      {"no_list.ply",
       "ply\nformat ascii 1.0\n" + vertex + "element face 0\nproperty int v\nend_header\n0 0 0\n",
       "vertex_indices"},
  };
  for (const auto& c : cases) {
    const fs::path path = WriteText(c.name, c.text);
    const std::string message = ErrorOf([&] { ReadPly(path); });
    EXPECT_NE(message.find(path.string()), std::string::npos) << c.name << ": " << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.name << ": " << message;
  }
}

TEST_F(PlyIoTest, BadFacesAndValuesAreErrors) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const std::string vertices = "0 0 0\n1 0 0\n0 1 0\n";
  const struct {
    const char* name;
    std::string text;
    const char* expected;
  } cases[] = {
      {"two_vertices.ply", header + vertices + "2 0 1\n", "face 0 has 2 vertices"},
      {"out_of_range.ply", header + vertices + "3 0 1 7\n", "vertex 7"},
      {"negative.ply", header + vertices + "3 0 -1 2\n", "face 0"},
      // ASCII values that are not numbers of the property's kind name the record and property.
      {"nan.ply", header + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n",
       "vertex 1: value 'nan' of property y is not a finite number"},
      {"inf.ply", header + "0 0 0\n1 0 0\n0 1 -inf\n3 0 1 2\n", "value '-inf' of property z"},
      {"letter.ply", header + vertices + "3 0 x 2\n",
       "face 0: value 'x' of property vertex_indices is not an integer"},
      {"fraction.ply", header + vertices + "3 0 1.5 2\n", "value '1.5' of property vertex_indices"},
      {"overflow.ply", header + "0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n",
       "vertex 1: value '1e39' of property x is out of the float range"},
      {"negative_length.ply", header + vertices + "-3 0 1 2\n",
       "face 0: negative list length -3 of property vertex_indices"},
      {"long_list.ply", header + vertices + "4000000000 0 1 2\n",
       "truncated or corrupt PLY data: it ends in face 0 of 1"},
  };
  for (const auto& c : cases) {
    const fs::path path = WriteText(c.name, c.text);
    const std::string message = ErrorOf([&] { ReadPly(path); });
    EXPECT_NE(message.find(path.string()), std::string::npos) << c.name << ": " << message;
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.name << ": " << message;
  }
}

// Three faces on edge 0-1 and a face with a repeated vertex: the file's vertices and faces are
// kept as they are, without duplicated vertices or dropped faces.
TEST_F(PlyIoTest, NonManifoldAndDegenerateFacesKeepTheFileCounts) {
  const fs::path path =
      WriteText("fin.ply",
                "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float "
                "y\nproperty float z\n"
                "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 0 1 4\n3 0 0 2\n");
  const TriangleMesh mesh = ReadPly(path);
  ASSERT_EQ(mesh.vertices.size(), 5u);
  ASSERT_EQ(mesh.faces.size(), 4u);
  EXPECT_EQ(mesh.faces[2], Eigen::Vector3i(0, 1, 4));
  EXPECT_EQ(mesh.faces[3], Eigen::Vector3i(0, 0, 2));
  EXPECT_EQ(mesh.vertices[4], Eigen::Vector3f(0, 0, 1));
}

TEST_F(PlyIoTest, PolygonsAreFanTriangulatedWithTheirColour) {
  const fs::path path =
      WriteText("quad.ply",
                "ply\nformat ascii 1.0\ncomment a quad and a triangle\nelement vertex 5\nproperty "
                "float x\nproperty float y\n"
                "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                "element face 2\nproperty list uchar int vertex_indices\nproperty uchar "
                "red\nproperty uchar green\n"
                "property uchar blue\nend_header\n"
                "0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 128 128 128\n2 2 0 0 0 0\n"
                "4 0 1 2 3 200 100 50\n3 1 4 2 10 20 30\n");
  const TriangleMesh mesh = ReadPly(path);
  ASSERT_EQ(mesh.faces.size(), 3u);
  EXPECT_EQ(mesh.faces[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.faces[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.faces[2], Eigen::Vector3i(1, 4, 2));
  ASSERT_EQ(mesh.face_colors.size(), 3u);
  const Eigen::Vector3f quad(SrgbToLinear(200 / 255.0f), SrgbToLinear(100 / 255.0f),
                             SrgbToLinear(50 / 255.0f));
  EXPECT_EQ(mesh.face_colors[0], quad);
  EXPECT_EQ(mesh.face_colors[1], quad);
  EXPECT_EQ(mesh.face_colors[2],
            Eigen::Vector3f(SrgbToLinear(10 / 255.0f), SrgbToLinear(20 / 255.0f),
                            SrgbToLinear(30 / 255.0f)));
  ASSERT_EQ(mesh.vertex_colors.size(), 5u);
  EXPECT_EQ(mesh.vertex_colors[0], Eigen::Vector3f(1, 0, 0));
  EXPECT_FLOAT_EQ(mesh.vertex_colors[3][0], SrgbToLinear(128 / 255.0f));
}

// Header comments (the last line before end_header too) and 8-bit custom properties in ASCII
// do not shift the data.
TEST_F(PlyIoTest, CommentsAndEightBitCustomPropertiesDoNotShiftTheData) {
  std::string binary =
      "ply\nformat binary_little_endian 1.0\nobj_info made by hand\nelement vertex 3\n"
      "property float x\nproperty float y\nproperty float z\nelement face 1\n"
      "property list uchar int vertex_indices\ncomment the last header line\nend_header\n";
  const float v[9] = {0.5f, 0, 0, 1, 0, 0, 0, 1, 0};
  binary.append(reinterpret_cast<const char*>(v), sizeof v);
  binary.push_back(3);
  const int32_t indices[3] = {0, 1, 2};
  binary.append(reinterpret_cast<const char*>(indices), sizeof indices);
  const TriangleMesh from_binary = ReadPly(WriteText("comment.ply", binary));
  ASSERT_EQ(from_binary.vertices.size(), 3u);
  ASSERT_EQ(from_binary.faces.size(), 1u);
  EXPECT_EQ(from_binary.vertices[0], Eigen::Vector3f(0.5f, 0, 0));
  EXPECT_EQ(from_binary.faces[0], Eigen::Vector3i(0, 1, 2));

  const TriangleMesh from_ascii = ReadPly(WriteText(
      "uchar.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "property uchar label\nelement face 1\nproperty list uchar int vertex_indices\nproperty "
      "uchar label\n"
      "property float albedo_r\nproperty float albedo_g\nproperty float albedo_b\nend_header\n"
      "0 0 0 12\n1 0 0 200\n0 1 0 7\n3 0 1 2 12 0.5 0.25 0.125"));  // no final newline either
  ASSERT_EQ(from_ascii.face_colors.size(), 1u);
  EXPECT_EQ(from_ascii.face_colors[0], Eigen::Vector3f(0.5f, 0.25f, 0.125f));
  EXPECT_EQ(from_ascii.vertices[1], Eigen::Vector3f(1, 0, 0));
}

// Comment lines right before end_header (and elsewhere in the header) of a binary file with
// normals, vertex colours and face colours: every value reads back exactly.
TEST_F(PlyIoTest, BinaryFileWithACommentBeforeEndHeaderReadsExactly) {
  const TriangleMesh mesh = TestMesh();
  const fs::path path = Path("mesh.ply");
  WritePly(path, mesh);
  std::string text = ReadAll(path);
  const size_t end = text.find("end_header\n");
  ASSERT_NE(end, std::string::npos);
  text.insert(end, "comment written by hand\ncomment the last header line\n");
  text.insert(text.find("element vertex"), "obj_info before the vertices\n");
  WriteText("mesh.ply", text);
  ExpectSameMesh(mesh, ReadPly(path));
}

// Two non-manifold meshes of 5 vertices and 4 faces, written in binary and ASCII: three faces on
// edge 0-1 (a fin), and two triangles sharing only vertex 0 (a bowtie) with a fan on the others.
// They read back as 5 vertices / 4 faces with the same indices and per-face colours.
TEST_F(PlyIoTest, NonManifoldMeshesOfFiveVerticesAndFourFacesReadAsTheyAre) {
  TriangleMesh fin;
  fin.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  fin.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}, {2, 3, 4}};
  TriangleMesh bowtie;
  bowtie.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
  bowtie.faces = {{0, 1, 2}, {0, 3, 4}, {1, 3, 2}, {3, 1, 4}};
  for (TriangleMesh* mesh : {&fin, &bowtie}) {
    for (int f = 0; f < 4; ++f) mesh->face_colors.emplace_back(0.1f * f, 0.5f, 1.0f - 0.2f * f);
    for (const bool binary : {true, false}) {
      PlyWriteOptions options;
      options.binary = binary;
      const fs::path path = Path(binary ? "binary.ply" : "ascii.ply");
      WritePly(path, *mesh, options);
      const TriangleMesh read = ReadPly(path);
      ASSERT_EQ(read.vertices.size(), 5u) << path;
      ASSERT_EQ(read.faces.size(), 4u) << path;
      ExpectSameMesh(*mesh, read);
    }
  }
}

// Layouts other writers produce: the face element before the vertex element, a list property in
// an element before the faces, a ushort list length with uint indices, a face property before
// the index list, double positions, a vertex_index list.
TEST_F(PlyIoTest, ElementAndPropertyLayoutsOfOtherWritersRead) {
  const TriangleMesh faces_first = ReadPly(WriteText(
      "faces_first.ply",
      "ply\nformat ascii 1.0\nelement face 2\nproperty float albedo_r\nproperty float albedo_g\n"
      "property float albedo_b\nproperty list uchar int vertex_index\nelement vertex 4\n"
      "property double x\nproperty double y\nproperty double z\nend_header\n"
      "0.5 0.25 0.125 3 0 1 2\n1 1 1 3 2 1 3\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n"));
  ASSERT_EQ(faces_first.vertices.size(), 4u);
  ASSERT_EQ(faces_first.faces.size(), 2u);
  EXPECT_EQ(faces_first.faces[1], Eigen::Vector3i(2, 1, 3));
  EXPECT_EQ(faces_first.vertices[3], Eigen::Vector3f(1, 1, 0));
  ASSERT_EQ(faces_first.face_colors.size(), 2u);
  EXPECT_EQ(faces_first.face_colors[0], Eigen::Vector3f(0.5f, 0.25f, 0.125f));

  std::string binary =
      "ply\nformat binary_little_endian 1.0\nelement group 1\nproperty list uchar int members\n"
      "element vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
      "element face 1\nproperty uchar flags\nproperty list ushort uint vertex_indices\n"
      "end_header\n";
  binary += std::string("\x02\x07\0\0\0\x08\0\0\0", 9);
  const double positions[12] = {0.1, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  binary.append(reinterpret_cast<const char*>(positions), sizeof positions);
  binary += std::string("\x05\x04\0", 3);
  const uint32_t corners[4] = {0, 1, 2, 3};
  binary.append(reinterpret_cast<const char*>(corners), sizeof corners);
  const TriangleMesh quad = ReadPly(WriteText("quad.ply", binary));
  ASSERT_EQ(quad.vertices.size(), 4u);
  EXPECT_EQ(quad.vertices[0], Eigen::Vector3f(static_cast<float>(0.1), 0, 0));
  ASSERT_EQ(quad.faces.size(), 2u);  // fan-triangulated
  EXPECT_EQ(quad.faces[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(quad.faces[1], Eigen::Vector3i(0, 2, 3));
}

// A binary face with a corrupt list length (4e9 corners) is a truncated file, found before the
// corners are allocated; a corner index beyond int is named as it is.
TEST_F(PlyIoTest, CorruptBinaryFaceListsAreErrors) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uint uint vertex_indices\nend_header\n";
  const std::string vertices(36, '\0');
  auto face = [](uint32_t length, uint32_t last) {
    const uint32_t values[4] = {length, 0, 1, last};
    return std::string(reinterpret_cast<const char*>(values), sizeof values);
  };
  const fs::path corrupt = WriteText("corrupt.ply", header + vertices + face(4000000000u, 2));
  EXPECT_EQ(ErrorOf([&] { ReadPly(corrupt); }),
            corrupt.string() + ": truncated or corrupt PLY data: it ends in face 0 of 1");
  const fs::path big = WriteText("big.ply", header + vertices + face(3, 4294967295u));
  EXPECT_EQ(ErrorOf([&] { ReadPly(big); }),
            big.string() + ": face 0 uses vertex 4294967295 but the file has 3 vertices");
}

TEST_F(PlyIoTest, EmptyMeshRoundTrips) {
  const fs::path path = Path("empty_mesh.ply");
  WritePly(path, TriangleMesh());
  const TriangleMesh read = ReadPly(path);
  EXPECT_TRUE(read.vertices.empty());
  EXPECT_TRUE(read.faces.empty());
}

// Counts declared by "element <name> <n>" in a PLY header.
std::optional<size_t> HeaderCount(const fs::path& path, const std::string& element) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream words(line);
    std::string keyword, name;
    size_t count = 0;
    if (words >> keyword >> name >> count && keyword == "element" && name == element) return count;
  }
  return std::nullopt;
}

TEST(PlyIoSharedDataTest, ReadsCornellBoxGeometryWithAlbedo) {
  GS_REQUIRE_SHARED_DATA(data_dir);
  const std::optional<fs::path> data = data_dir;
  for (const char* file : {"scene.ply", "all_geometry.ply"}) {
    const fs::path path = *data / "cbox-cycles" / "geometry" / file;
    ASSERT_TRUE(fs::exists(path)) << path;
    const std::optional<size_t> vertices = HeaderCount(path, "vertex");
    const std::optional<size_t> faces = HeaderCount(path, "face");
    ASSERT_TRUE(vertices && faces) << path;
    const TriangleMesh mesh = ReadPly(path);
    EXPECT_EQ(mesh.vertices.size(), *vertices) << path;
    EXPECT_EQ(mesh.faces.size(), *faces) << path;  // all triangles in these files
    ASSERT_EQ(mesh.face_colors.size(), mesh.faces.size()) << path;
    // Faces 6 and 7 are the red left wall (objects.json: id 3, left_wall_red, face_range [6, 8]).
    for (size_t f : {6, 7}) {
      EXPECT_EQ(mesh.face_colors[f], Eigen::Vector3f(0.63f, 0.065f, 0.05f))
          << path << " face " << f;
      EXPECT_GT(mesh.face_colors[f][0], mesh.face_colors[f][1]) << path << " face " << f;
    }
    if (std::string(file) == "scene.ply") {
      ASSERT_EQ(mesh.normals.size(), mesh.vertices.size());
      EXPECT_EQ(mesh.normals[0], Eigen::Vector3f(0, 0, 1));
    }
  }
}

}  // namespace
}  // namespace genscene
