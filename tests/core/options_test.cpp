#include "core/options.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/frame_source.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

using test::ErrorOf;

TEST(Options, ConfigFileSetsTypedValues) {
  test::TempDir dir;
  std::ofstream(dir / "c.json") << R"({"source": {"depth_scale": 1000, "camera_response": "linear",
                                      "max_frames": 3}, "fusion": {"voxel_size": 0.01}})";
  ConfigFile config(dir / "c.json");
  SourceOptions source;
  config.Apply(source);
  EXPECT_EQ(source.depth_scale, 1000.0);
  EXPECT_EQ(source.camera_response, "linear");
  EXPECT_EQ(source.max_frames, 3);
  EXPECT_EQ(source.stride, 1);  // untouched default
  // "fusion" belongs to another stage: accepted by this app, checked by the one that applies it.
  EXPECT_NO_THROW(config.CheckNoUnknown());
}

TEST(Options, UnknownKeyIsNamed) {
  test::TempDir dir;
  std::ofstream(dir / "c.json") << R"({"source": {"depth_scael": 1000}})";
  ConfigFile config(dir / "c.json");
  SourceOptions source;
  config.Apply(source);
  const std::string what = ErrorOf([&] { config.CheckNoUnknown(); });
  EXPECT_NE(what.find("unknown key 'source.depth_scael'"), std::string::npos) << what;
  EXPECT_NE(what.find("c.json"), std::string::npos) << what;
}

TEST(Options, UnknownSectionAndWrongTypeAndBadJson) {
  test::TempDir dir;
  std::ofstream(dir / "a.json") << R"({"sorce": {}})";
  ConfigFile a(dir / "a.json");
  EXPECT_NE(ErrorOf([&] { a.CheckNoUnknown(); }).find("unknown section 'sorce'"),
            std::string::npos);

  std::ofstream(dir / "b.json") << R"({"source": {"max_frames": "ten"}})";
  ConfigFile b(dir / "b.json");
  SourceOptions source;
  EXPECT_NE(ErrorOf([&] { b.Apply(source); }).find("'source.max_frames' must be an integer"),
            std::string::npos);

  // 2^64 - 1 once wrapped to -1 through long long, and -1 was taken without an error.
  for (const char* big : {"18446744073709551615", "4294967297"}) {
    std::ofstream(dir / "b.json") << R"({"source": {"max_frames": )" << big << "}}";
    ConfigFile big_config(dir / "b.json");
    EXPECT_CONTAINS(ErrorOf([&] { big_config.Apply(source); }),
                    std::string("'source.max_frames' must be a 32-bit integer, got ") + big);
  }

  std::ofstream(dir / "c.json") << R"({"source": {"max_frames": 3)";
  EXPECT_NE(ErrorOf([&] { ConfigFile c(dir / "c.json"); }).find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ConfigFile d(dir / "missing.json"); }).find("not found"),
            std::string::npos);
}

TEST(Options, ValidateRejectsOutOfRangeWithTheValue) {
  SourceOptions source;
  EXPECT_NO_THROW(source.Validate());
  source.stride = 0;
  EXPECT_NE(ErrorOf([&] { source.Validate(); }).find("stride = 0"), std::string::npos);
  source = SourceOptions();
  source.depth_scale = -5;
  EXPECT_NE(ErrorOf([&] { source.Validate(); }).find("depth_scale = -5"), std::string::npos);
  source = SourceOptions();
  source.depth_encoding = "kinect";
  EXPECT_NE(ErrorOf([&] { source.Validate(); }).find("'kinect' is not one of"), std::string::npos);
}

TEST(Options, FlagNames) {
  EXPECT_EQ(FlagName("voxel_size"), "--voxel-size");
  EXPECT_EQ(FlagName("seed"), "--seed");
}

}  // namespace
}  // namespace genscene
