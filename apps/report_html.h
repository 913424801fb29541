// report.html: the Markdown report as a page a browser opens from disk, with the model in 3D.
//
// The Markdown (GitHub tables) is turned into HTML by cmark-gfm. Above it, a three.js view
// (Debian's libjs-three, its classic non-module builds copied to report/three/) shows
// export/model.glb with its albedo atlas, the keyframe cameras' first pose as the start view and
// the point lights as small markers. A page opened from disk (file://) may not read files next to
// it, so the .glb travels inside report/model_glb.js as base64. Without libjs-three or model.glb
// the page is written without the 3D view and says why.
//
// The page marks its state for tools: <body data-model="loaded"> once the model is drawn,
// "error" (with the reason in #view3d-status and on the console) when it could not be.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace genscene::apps {

struct ReportHtmlInputs {
  std::string markdown;             // the report, as written to report.md
  std::filesystem::path glb;        // the model to show; empty or missing: no 3D view
  std::filesystem::path three_dir;  // libjs-three's folder (three.min.js, examples/js/...)
};

// Writes dir/report.html (last, atomically) and what it loads (dir/three/, dir/model_glb.js).
// Returns the warnings (a 3D view left out, and why).
std::vector<std::string> WriteReportHtml(const std::filesystem::path& dir,
                                         const ReportHtmlInputs& inputs);

// Where Debian's libjs-three puts three.js.
inline const char* kDebianThreeDir = "/usr/share/javascript/three";

// Markdown (CommonMark with GitHub tables) to HTML. Throws Error when cmark-gfm fails.
std::string MarkdownToHtml(const std::string& markdown);

// RFC 4648 base64 of `bytes`.
std::string Base64(const std::string& bytes);

}  // namespace genscene::apps
