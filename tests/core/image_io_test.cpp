#include "core/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "core/check.h"
#include "core/rng.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

TEST(Color, SrgbRoundTripAndKnownValues) {
  EXPECT_FLOAT_EQ(SrgbToLinear(0.0f), 0.0f);
  EXPECT_FLOAT_EQ(SrgbToLinear(1.0f), 1.0f);
  EXPECT_NEAR(SrgbToLinear(0.5f), 0.21404f, 1e-5);  // IEC 61966-2-1
  for (float x = 0.0f; x <= 1.0f; x += 0.01f) EXPECT_NEAR(LinearToSrgb(SrgbToLinear(x)), x, 1e-5);
  const CameraResponse gamma = CameraResponse::Parse("gamma:2.0");
  EXPECT_FLOAT_EQ(gamma.ToLinear(0.5f), 0.25f);
  EXPECT_THROW(CameraResponse::Parse("log"), Error);
  EXPECT_THROW(CameraResponse::Parse("gamma:0"), Error);
}

ImageRgb RandomImage(int w, int h) {
  ImageRgb image(w, h);
  CounterRng rng(5, 6);
  for (auto& p : image.pixels())
    p = Eigen::Vector3f(rng.Uniform(), rng.Uniform() * 4.0f, rng.Uniform() * 1e-3f);
  return image;
}

TEST(Color, TabledSrgbIsWithinItsStepOfTheCurveAndClamps) {
  double worst = 0.0;
  for (int i = 0; i <= 100000; ++i) {
    const float x = static_cast<float>(i) / 100000.0f;
    worst = std::max<double>(worst, std::abs(LinearToSrgbTabled(x) - LinearToSrgb(x)));
  }
  EXPECT_LT(worst, 4.5e-4);
  EXPECT_EQ(LinearToSrgbTabled(0.0f), 0.0f);
  EXPECT_EQ(LinearToSrgbTabled(1.0f), LinearToSrgb(1.0f));
  EXPECT_EQ(LinearToSrgbTabled(2.0f), LinearToSrgb(1.0f));
  EXPECT_EQ(LinearToSrgbTabled(-1.0f), 0.0f);
  EXPECT_EQ(LinearToSrgbTabled(std::nanf("")), 0.0f);
  EXPECT_EQ(LinearToSrgbTabled(std::numeric_limits<float>::infinity()), 0.0f);
}

TEST(ImageIo, ExrRoundTripIsExact) {
  test::TempDir dir;
  const ImageRgb image = RandomImage(37, 21);
  WriteExr(dir / "a.exr", image);
  const ImageRgb back = ReadColorImage(dir / "a.exr", CameraResponse());
  ASSERT_TRUE(back.SameSize(image));
  for (size_t i = 0; i < image.size(); ++i) EXPECT_EQ(back.pixels()[i], image.pixels()[i]) << i;
}

TEST(ImageIo, PngRoundTripWithinQuantisation) {
  test::TempDir dir;
  ImageRgb image = RandomImage(16, 9);
  for (auto& p : image.pixels()) p = p.cwiseMin(1.0f);
  WritePng(dir / "a.png", image);
  const ImageRgb back = ReadColorImage(dir / "a.png", CameraResponse());
  for (size_t i = 0; i < image.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      // Half an 8-bit step in the encoded domain.
      EXPECT_NEAR(LinearToSrgb(back.pixels()[i][c]), LinearToSrgb(image.pixels()[i][c]),
                  0.5 / 255 + 1e-6);
    }
  }
}

// Every 8-bit code of each channel decodes to the camera response of code / 255, channels in RGB
// order, for every response.
TEST(ImageIo, EightBitCodesDecodeThroughTheCameraResponse) {
  test::TempDir dir;
  cv::Mat bgr(4, 64, CV_8UC3);
  for (int i = 0; i < 256; ++i) {
    bgr.at<cv::Vec3b>(i / 64, i % 64) =
        cv::Vec3b(static_cast<uint8_t>(255 - i), static_cast<uint8_t>((i * 7) % 256),
                  static_cast<uint8_t>(i));
  }
  ASSERT_TRUE(cv::imwrite((dir / "codes.png").string(), bgr));
  for (const char* text : {"srgb", "linear", "gamma:2.2"}) {
    const CameraResponse response = CameraResponse::Parse(text, "test");
    const ImageRgb image = ReadColorImage(dir / "codes.png", response);
    for (int i = 0; i < 256; ++i) {
      const Eigen::Vector3f rgb = image(i % 64, i / 64);
      // (code / 255 rounds differently in OpenCV's conversion: a few units in the last place)
      EXPECT_NEAR(rgb[0], response.ToLinear(i / 255.0f), 1e-6) << text << " code " << i;
      EXPECT_NEAR(rgb[1], response.ToLinear(((i * 7) % 256) / 255.0f), 1e-6) << text << " " << i;
      EXPECT_NEAR(rgb[2], response.ToLinear((255 - i) / 255.0f), 1e-6) << text << " " << i;
    }
  }
}

TEST(ImageIo, DepthPngRoundTripAtScale5000) {
  test::TempDir dir;
  ImageDepth depth(40, 30);
  CounterRng rng(9, 9);
  for (auto& z : depth.pixels()) z = rng.Uniform() < 0.1f ? 0.0f : 0.3f + 10.0f * rng.Uniform();
  WriteDepthPng(dir / "d.png", depth, 5000.0);
  const ImageDepth back = ReadDepthImage(dir / "d.png");
  for (size_t i = 0; i < depth.size(); ++i) {
    EXPECT_NEAR(back.pixels()[i], depth.pixels()[i], 0.5 / 5000.0 + 1e-6);
    EXPECT_EQ(back.pixels()[i] == 0.0f, depth.pixels()[i] == 0.0f);
  }
  // The raw 16-bit value is depth * 5000 (TUM).
  ImageDepth one(1, 1, 1.0f);
  WriteDepthPng(dir / "one.png", one, 5000.0);
  DepthEncoding raw;
  raw.scale = 1.0;
  EXPECT_EQ(ReadDepthImage(dir / "one.png", raw)(0, 0), 5000.0f);
}

TEST(ImageIo, DepthExrRoundTripIsExact) {
  test::TempDir dir;
  ImageDepth depth(11, 7, 0.0f);
  for (size_t i = 0; i < depth.size(); ++i)
    depth.pixels()[i] = 0.1f * static_cast<float>(i) + 1e-4f;
  WriteDepthExr(dir / "d.exr", depth);
  const ImageDepth back = ReadDepthImage(dir / "d.exr");
  for (size_t i = 0; i < depth.size(); ++i) EXPECT_EQ(back.pixels()[i], depth.pixels()[i]);
}

TEST(ImageIo, DepthTooFarFor16BitsIsAnError) {
  test::TempDir dir;
  ImageDepth depth(2, 2, 20.0f);  // 20 m * 5000 > 65535
  EXPECT_THROW(WriteDepthPng(dir / "d.png", depth, 5000.0), Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "d.png"));
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".tmp-"), 0);
}

void ExpectErrorNaming(const std::function<void()>& f, const std::string& needle,
                       const std::string& file) {
  try {
    f();
    ADD_FAILURE() << "no error for " << file;
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file), std::string::npos) << what;
    EXPECT_NE(what.find(needle), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "message is not one line: " << what;
  }
}

TEST(ImageIo, BadFilesGiveOneLineErrorsNamingTheFile) {
  test::TempDir dir;
  ExpectErrorNaming([&] { ReadColorImage(dir / "missing.png", CameraResponse()); }, "not found",
                    "missing.png");
  std::ofstream(dir / "empty.png").close();
  ExpectErrorNaming([&] { ReadDepthImage(dir / "empty.png"); }, "empty", "empty.png");
  // A PNG cut after its first 100 bytes.
  ImageDepth depth(64, 64, 1.0f);
  WriteDepthPng(dir / "full.png", depth);
  {
    std::ifstream in(dir / "full.png", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(dir / "cut.png", std::ios::binary) << bytes.substr(0, 100);
    std::ofstream(dir / "garbage.png", std::ios::binary) << "this is not an image at all";
  }
  ExpectErrorNaming([&] { ReadDepthImage(dir / "cut.png"); }, "cannot decode", "cut.png");
  ExpectErrorNaming([&] { ReadColorImage(dir / "garbage.png", CameraResponse()); }, "cannot decode",
                    "garbage.png");
  // A colour image is not a depth image.
  WritePng(dir / "color.png", ImageRgb(4, 4, Eigen::Vector3f(0.5f, 0.5f, 0.5f)));
  ExpectErrorNaming([&] { ReadDepthImage(dir / "color.png"); }, "channels", "color.png");
}

TEST(ImageIo, NanInfNegativeDepthAreRejected) {
  test::TempDir dir;
  for (float bad :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -1.0f}) {
    ImageDepth depth(8, 8, 1.0f);
    depth(3, 5) = bad;
    WriteDepthExr(dir / "bad.exr", depth);
    ExpectErrorNaming([&] { ReadDepthImage(dir / "bad.exr"); }, "pixel (3, 5)", "bad.exr");
  }
}

TEST(ImageIo, NanAndInfiniteColourAreRejectedNegativeKept) {
  test::TempDir dir;
  for (float bad :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    for (int c = 0; c < 3; ++c) {
      ImageRgb image(8, 8, Eigen::Vector3f(0.5f, 0.25f, 0.125f));
      image(3, 5)[c] = bad;
      image(6, 7)[c] = bad;
      WriteExr(dir / "bad.exr", image);
      ExpectErrorNaming([&] { ReadColorImage(dir / "bad.exr", CameraResponse()); }, "2 pixels",
                        "bad.exr");
      ExpectErrorNaming([&] { ReadColorImage(dir / "bad.exr", CameraResponse()); }, "pixel (3, 5)",
                        "bad.exr");
    }
  }
  // A negative value is a valid observation of a linear image (filters with negative lobes).
  ImageRgb image(8, 8, Eigen::Vector3f(0.5f, 0.25f, 0.125f));
  image(2, 1) = Eigen::Vector3f(-0.01f, 0.0f, 0.3f);
  WriteExr(dir / "negative.exr", image);
  const ImageRgb back = ReadColorImage(dir / "negative.exr", CameraResponse());
  EXPECT_EQ(back(2, 1), image(2, 1));
}

TEST(ImageIo, RealFormatsDecode) {
  GS_REQUIRE_SHARED_DATA(data);
  const auto other = data / "real/open3d-testdata-rgbd/other_formats";
  // TUM: 16-bit PNG, 5000 per meter.
  const ImageDepth tum = ReadDepthImage(other / "TUM_depth.png");
  EXPECT_EQ(tum.width(), 640);
  EXPECT_EQ(tum.height(), 480);
  // NYU raw disparity and SUN rotated millimetres decode to indoor ranges.
  DepthEncoding nyu;
  nyu.kind = DepthEncoding::Kind::kNyuDisparity;
  DepthEncoding sun;
  sun.kind = DepthEncoding::Kind::kSunRotated;
  for (const auto& [path, encoding] : std::vector<std::pair<std::filesystem::path, DepthEncoding>>{
           {other / "TUM_depth.png", DepthEncoding()},
           {other / "NYU_depth.pgm", nyu},
           {other / "SUN_depth.png", sun}}) {
    const ImageDepth d = ReadDepthImage(path, encoding);
    double lo = 1e9, hi = 0.0;
    size_t valid = 0;
    for (float z : d.pixels()) {
      if (z <= 0.0f) continue;
      ++valid;
      lo = std::min<double>(lo, z);
      hi = std::max<double>(hi, z);
    }
    EXPECT_GT(valid, d.size() / 2) << path;
    EXPECT_GT(lo, 0.2) << path;
    EXPECT_LT(hi, 12.0) << path;
  }
  const ImageRgb nyu_color = ReadColorImage(other / "NYU_color.ppm", CameraResponse());
  EXPECT_EQ(nyu_color.width(), 640);
  const ImageRgb sun_color = ReadColorImage(other / "SUN_color.jpg", CameraResponse());
  EXPECT_GT(sun_color.width(), 0);
}

// An EXR written by OpenEXR itself, with the named FLOAT channels; channel c holds c + x / 10 + y.
void WriteExrChannels(const std::filesystem::path& path, int width, int height,
                      const std::vector<std::string>& names) {
  Imf::Header header(width, height);
  std::vector<std::vector<float>> planes;
  for (size_t c = 0; c < names.size(); ++c) {
    header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
    planes.emplace_back(static_cast<size_t>(width * height));
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x)
        planes[c][y * width + x] = static_cast<float>(c) + 0.1f * x + y;
    }
  }
  Imf::OutputFile file(path.c_str(), header);
  Imf::FrameBuffer buffer;
  for (size_t c = 0; c < names.size(); ++c) {
    buffer.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(planes[c].data()),
                                       sizeof(float), sizeof(float) * width));
  }
  file.setFrameBuffer(buffer);
  file.writePixels(height);
}

TEST(ImageIo, ExrChannelsAreChosenByName) {
  test::TempDir dir;
  // A single channel of any name is a depth image (Blender writes "Z", others "depth" or "Y").
  WriteExrChannels(dir / "z.exr", 4, 3, {"Z"});
  const ImageDepth z = ReadDepthImage(dir / "z.exr");
  ASSERT_EQ(z.width(), 4);
  EXPECT_FLOAT_EQ(z(3, 2), 0.3f + 2.0f);
  // R, G, B are colour, whatever else the file holds (here alpha and depth).
  WriteExrChannels(dir / "rgbaz.exr", 4, 3, {"A", "B", "G", "R", "Z"});
  const ImageRgb rgb = ReadColorImage(dir / "rgbaz.exr", CameraResponse());
  // Channels are stored sorted by name: A 0, B 1, G 2, R 3, Z 4.
  EXPECT_FLOAT_EQ(rgb(1, 2)[0], 3.0f + 0.1f + 2.0f);
  EXPECT_FLOAT_EQ(rgb(1, 2)[1], 2.0f + 0.1f + 2.0f);
  EXPECT_FLOAT_EQ(rgb(1, 2)[2], 1.0f + 0.1f + 2.0f);
  // A colour file is no depth image.
  ExpectErrorNaming([&] { ReadDepthImage(dir / "rgbaz.exr"); }, "3 channels", "rgbaz.exr");
  // Two channels that are neither colour nor luminance: no guessing.
  WriteExrChannels(dir / "az.exr", 4, 3, {"A", "Z"});
  ExpectErrorNaming([&] { ReadDepthImage(dir / "az.exr"); }, "EXR channels (A, Z)", "az.exr");
}

}  // namespace
}  // namespace genscene
