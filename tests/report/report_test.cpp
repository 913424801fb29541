// report.md's tracking section from a workspace's fusion.json: the frames where tracking did more
// than follow the camera (loops closed, relocalised, started from features, lost, degenerate,
// blank).
#include "apps/report.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "tests/test_util.h"

namespace genscene::apps {
namespace {

nlohmann::json Frame(int index, const std::string& status, bool feature_start = false,
                     std::optional<double> relocalised_against = std::nullopt) {
  nlohmann::json f = {{"index", index},       {"status", status}, {"feature_start", feature_start},
                      {"ms_preprocess", 1.0}, {"ms_track", 2.0},  {"ms_integrate", 3.0},
                      {"ms_raycast", 4.0}};
  f["relocalised_against_t"] =
      relocalised_against ? nlohmann::json(*relocalised_against) : nlohmann::json(nullptr);
  return f;
}

TEST(Report, TrackingListsRelocalisationsFeatureStartsAndLostFrames) {
  test::TempDir dir;
  nlohmann::json frames = nlohmann::json::array();
  frames.push_back(Frame(0, "initial"));
  frames.push_back(Frame(1, "tracked", true));
  frames.push_back(Frame(2, "lost"));
  frames.push_back(Frame(3, "tracked", true, 0.5));
  for (int i = 4; i < 30; ++i) frames.push_back(Frame(i, "blank"));
  test::WriteFile(dir / "fusion.json", nlohmann::json({{"frames", frames}}).dump());
  const Workspace ws(dir.path());
  const std::string md = ReadTextFile(WriteReport(ws, ReportOptions(), 1));
  EXPECT_CONTAINS(md, "| tracking | frames |");
  EXPECT_CONTAINS(md, "| relocalised | 3 (keyframe t = 0.500) |");
  EXPECT_CONTAINS(md, "| started from features | 1 |");
  EXPECT_CONTAINS(md, "| lost | 2 |");
  // 26 blank frames: the first 20 listed, then how many more.
  EXPECT_CONTAINS(md,
                  "| blank | 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, "
                  "21, 22, 23 and 6 more |");
  EXPECT_EQ(md.find("| degenerate |"), std::string::npos);
  EXPECT_EQ(md.find("Every frame was tracked"), std::string::npos);
}

TEST(Report, TrackingListsTheLoopsClosed) {
  test::TempDir dir;
  nlohmann::json frames = nlohmann::json::array({Frame(0, "initial"), Frame(1, "tracked")});
  nlohmann::json closed = Frame(2, "tracked");
  closed["loop_closure"] = {
      {"against_t", 0.0}, {"largest_move_m", 0.0812}, {"reintegrated_frames", 3}};
  frames.push_back(closed);
  closed = Frame(3, "tracked");
  closed["loop_closure"] = {
      {"against_t", 0.25}, {"largest_move_m", 0.001}, {"reintegrated_frames", 0}};
  frames.push_back(closed);
  test::WriteFile(dir / "fusion.json", nlohmann::json({{"frames", frames}}).dump());
  const std::string md = ReadTextFile(WriteReport(Workspace(dir.path()), ReportOptions(), 1));
  EXPECT_CONTAINS(md,
                  "| loop closed | 2 (frame t = 0.000, poses moved up to 8.12 cm, 3 frames "
                  "integrated again), 3 (frame t = 0.250, poses moved up to 0.10 cm) |");
  EXPECT_EQ(md.find("Every frame was tracked"), std::string::npos);
}

TEST(Report, TrackingSaysWhenEveryFrameFollowedTheOneBefore) {
  test::TempDir dir;
  nlohmann::json frames = nlohmann::json::array({Frame(0, "initial"), Frame(1, "tracked")});
  test::WriteFile(dir / "fusion.json", nlohmann::json({{"frames", frames}}).dump());
  const std::string md = ReadTextFile(WriteReport(Workspace(dir.path()), ReportOptions(), 1));
  EXPECT_CONTAINS(md, "Every frame was tracked from the one before it.");
  EXPECT_EQ(md.find("| tracking | frames |"), std::string::npos);
}

}  // namespace
}  // namespace genscene::apps
