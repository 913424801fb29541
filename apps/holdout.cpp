#include "apps/holdout.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "apps/scene_inputs.h"
#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/ply_io.h"
#include "render/path_tracer.h"

namespace genscene::apps {

namespace fs = std::filesystem;
using namespace genscene::inverse;
using namespace genscene::render;

namespace {

float Luminance(const Eigen::Vector3f& c) {
  return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z();
}

// The sRGB-encoded luminance of an image, clipped to [0, 1].
cv::Mat EncodedLuminance(const ImageRgb& image) {
  cv::Mat out(image.height(), image.width(), CV_32F);
  for (int v = 0; v < image.height(); ++v) {
    for (int u = 0; u < image.width(); ++u) {
      out.at<float>(v, u) = LinearToSrgb(std::clamp(Luminance(image(u, v)), 0.0f, 1.0f));
    }
  }
  return out;
}

// What the model predicts per pixel from the camera ray's first hit: the albedo and the texture.
struct FirstHits {
  Image<uint8_t> mask;  // 1: the ray hits the model and the frame's colour is finite
  ImageRgb albedo, texture;
};

FirstHits TraceFirstHits(const PathTracer& tracer, const MeshColors& texture,
                         const PosedImage& frame) {
  const CameraIntrinsics& k = frame.view.intrinsics;
  FirstHits out{Image<uint8_t>(k.width, k.height, 0), ImageRgb(k.width, k.height),
                ImageRgb(k.width, k.height)};
  const SceneMesh& mesh = tracer.scene().meshes.front();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      if (!frame.image(u, v).allFinite()) continue;
      const auto hit = tracer.PixelCentreHit(frame.view, u, v);
      if (!hit || hit->mesh != 0) continue;
      out.mask(u, v) = 1;
      out.albedo(u, v) = mesh.albedo.Eval(mesh.mesh, hit->face, hit->b1, hit->b2);
      out.texture(u, v) = texture.Linear(hit->face, hit->b1, hit->b2);
    }
  }
  return out;
}

// g P where the mask is set, the reference elsewhere (so that SSIM's window sees no false edge).
ImageRgb Gained(const ImageRgb& prediction, const Eigen::Vector3d& gain, const ImageRgb& reference,
                const Image<uint8_t>& mask) {
  ImageRgb out = reference;
  for (size_t i = 0; i < out.size(); ++i) {
    if (mask.data()[i]) out.data()[i] = prediction.data()[i].cwiseProduct(gain.cast<float>());
  }
  return out;
}

nlohmann::ordered_json ToJson(const HeldOutScore& s) {
  return {
      {"gain", {s.gain.x(), s.gain.y(), s.gain.z()}}, {"relative_rmse", s.rmse}, {"ssim", s.ssim}};
}

nlohmann::ordered_json ToJson(const AgainstTruth& t) {
  return {{"model", ToJson(t.model)},
          {"texture_unlit", ToJson(t.texture)},
          {"albedo_ambient", ToJson(t.ambient)},
          {"frame", ToJson(t.frame)}};
}

void AddMean(HeldOutScore* mean, const HeldOutScore& score, double n) {
  mean->rmse += score.rmse / n;
  mean->ssim += score.ssim / n;
  mean->gain += score.gain / n;
}

}  // namespace

double MaskedSsim(const ImageRgb& a, const ImageRgb& b, const Image<uint8_t>& mask) {
  GS_CHECK(a.SameSize(b) && a.SameSize(mask));
  const cv::Mat x = EncodedLuminance(a), y = EncodedLuminance(b);
  const auto blur = [](const cv::Mat& m) {
    cv::Mat out;
    cv::GaussianBlur(m, out, cv::Size(11, 11), 1.5, 1.5, cv::BORDER_REFLECT);
    return out;
  };
  const cv::Mat mx = blur(x), my = blur(y);
  const cv::Mat sxx = blur(x.mul(x)) - mx.mul(mx), syy = blur(y.mul(y)) - my.mul(my),
                sxy = blur(x.mul(y)) - mx.mul(my);
  constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  double sum = 0.0;
  size_t n = 0;
  for (int v = 0; v < mask.height(); ++v) {
    for (int u = 0; u < mask.width(); ++u) {
      if (!mask(u, v)) continue;
      const double ux = mx.at<float>(v, u), uy = my.at<float>(v, u);
      sum += ((2.0 * ux * uy + c1) * (2.0 * sxy.at<float>(v, u) + c2)) /
             ((ux * ux + uy * uy + c1) * (sxx.at<float>(v, u) + syy.at<float>(v, u) + c2));
      ++n;
    }
  }
  return n > 0 ? sum / static_cast<double>(n) : 0.0;
}

HeldOutScore ScorePrediction(const ImageRgb& prediction, const ImageRgb& reference,
                             const Image<uint8_t>& mask) {
  Eigen::Vector3d pr = Eigen::Vector3d::Zero(), pp = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!mask.data()[i]) continue;
    const Eigen::Vector3d p = prediction.data()[i].cast<double>(),
                          r = reference.data()[i].cast<double>();
    pr += p.cwiseProduct(r);
    pp += p.cwiseProduct(p);
  }
  HeldOutScore s;
  for (int c = 0; c < 3; ++c) s.gain[c] = pp[c] > 0.0 ? pr[c] / pp[c] : 0.0;
  double err = 0.0, ref = 0.0;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!mask.data()[i]) continue;
    const Eigen::Vector3d r = reference.data()[i].cast<double>();
    err += (prediction.data()[i].cast<double>().cwiseProduct(s.gain) - r).squaredNorm();
    ref += r.squaredNorm();
  }
  s.rmse = ref > 0.0 ? std::sqrt(err / ref) : 0.0;
  s.ssim = MaskedSsim(Gained(prediction, s.gain, reference, mask), reference, mask);
  return s;
}

HeldOutEvaluation EvaluateHeldOut(const Workspace& ws, const LightEstimationOptions& lights,
                                  int spp, uint64_t seed, const Scene* truth, int truth_spp) {
  const std::vector<PosedImage> frames = ReadPosedImages(ws.HeldOut());
  if (frames.empty())
    throw Error(Format(ws.HeldOut().string(), ": no held-out frames to judge the model on"));
  const fs::path mesh_path = ws.ModelMesh();
  std::vector<std::string> warnings;
  Scene model = LoadGeometry({{}, mesh_path, ws.ModelAlbedo()}, ws, &warnings);
  model.voxel_lights = ReadLightsJson(ws.Lights());
  const MeshColors texture = ReadMeshColors(ws.Texture(), model.meshes.front().mesh);
  const PathTracer tracer(model);
  std::optional<PathTracer> truth_tracer;
  if (truth) truth_tracer.emplace(*truth);
  const fs::path dir = ws.EvaluationDir();
  fs::create_directories(dir);

  HeldOutEvaluation out;
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (size_t f = 0; f < frames.size(); ++f) {
    const PosedImage& frame = frames[f];
    const FirstHits hits = TraceFirstHits(tracer, texture, frame);
    RenderOptions paths = lights.paths;
    paths.spp = spp;
    paths.surface_only = true;  // as the mask and the baselines: where the model has a surface
    const RenderHalves halves = RenderInHalves(tracer, frame.view, paths, seed + 3000 + f,
                                               (seed + 3000 + f) ^ 0xD1B54A32D192ED03ull);
    const ImageRgb &a = halves.a, &b = halves.b, &render = halves.mean;

    HeldOutFrame r;
    r.timestamp = frame.view.timestamp;
    for (size_t i = 0; i < hits.mask.size(); ++i) r.pixels += hits.mask.data()[i];
    if (r.pixels == 0) continue;  // the model is not in view
    r.model = ScorePrediction(render, frame.image, hits.mask);
    r.texture = ScorePrediction(hits.texture, frame.image, hits.mask);
    r.ambient = ScorePrediction(hits.albedo, frame.image, hits.mask);
    double noise = 0.0, ref = 0.0;
    ImageRgb error(render.width(), render.height());
    for (size_t i = 0; i < render.size(); ++i) {
      if (!hits.mask.data()[i]) continue;
      const Eigen::Vector3d g = r.model.gain;
      noise += 0.25 * (a.data()[i] - b.data()[i]).cast<double>().cwiseProduct(g).squaredNorm();
      ref += frame.image.data()[i].cast<double>().squaredNorm();
      error.data()[i] =
          4.0f *
          (render.data()[i].cwiseProduct(g.cast<float>()) - frame.image.data()[i]).cwiseAbs();
    }
    r.noise = ref > 0.0 ? std::sqrt(noise / ref) : 0.0;

    char stem[32];
    std::snprintf(stem, sizeof(stem), "holdout_%02zu", f);
    WritePng(dir / (std::string(stem) + "_real.png"), frame.image);
    WritePng(dir / (std::string(stem) + "_model.png"),
             Gained(render, r.model.gain, ImageRgb(a.width(), a.height()), hits.mask));
    WritePng(dir / (std::string(stem) + "_texture.png"),
             Gained(hits.texture, r.texture.gain, ImageRgb(a.width(), a.height()), hits.mask));
    WritePng(dir / (std::string(stem) + "_ambient.png"),
             Gained(hits.albedo, r.ambient.gain, ImageRgb(a.width(), a.height()), hits.mask));
    WritePng(dir / (std::string(stem) + "_error.png"), error);
    if (truth_tracer) {
      RenderOptions paths;  // the true scene's full light transport, as the evaluation renders it
      paths.spp = truth_spp;
      const ImageRgb true_render =
          truth_tracer->Render(frame.view, paths, seed + 4000 + f).radiance;
      r.truth = AgainstTruth{ScorePrediction(render, true_render, hits.mask),
                             ScorePrediction(hits.texture, true_render, hits.mask),
                             ScorePrediction(hits.albedo, true_render, hits.mask),
                             ScorePrediction(frame.image, true_render, hits.mask)};
      WritePng(dir / (std::string(stem) + "_truth.png"), true_render);
    }
    nlohmann::ordered_json entry = {{"timestamp", r.timestamp},
                                    {"pixels", r.pixels},
                                    {"noise", r.noise},
                                    {"model", ToJson(r.model)},
                                    {"texture_unlit", ToJson(r.texture)},
                                    {"albedo_ambient", ToJson(r.ambient)}};
    entry["images"] = stem;  // holdout_NN_*.png: NN is the frame's index in holdout/
    if (r.truth) entry["against_truth"] = ToJson(*r.truth);
    list.push_back(entry);
    out.frames.push_back(r);
  }
  if (out.frames.empty())
    throw Error(Format(ws.HeldOut().string(), ": the model is in view of no held-out frame"));
  const double n = static_cast<double>(out.frames.size());
  if (truth) out.truth = AgainstTruth();
  for (const HeldOutFrame& r : out.frames) {
    AddMean(&out.model, r.model, n);
    AddMean(&out.texture, r.texture, n);
    AddMean(&out.ambient, r.ambient, n);
    out.noise += r.noise / n;
    if (out.truth) {
      AddMean(&out.truth->model, r.truth->model, n);
      AddMean(&out.truth->texture, r.truth->texture, n);
      AddMean(&out.truth->ambient, r.truth->ambient, n);
      AddMean(&out.truth->frame, r.truth->frame, n);
    }
  }
  nlohmann::ordered_json report;
  report["spp"] = spp;
  if (truth) report["truth_spp"] = truth_spp;
  report["frames"] = list;
  report["mean"] = {{"model", ToJson(out.model)},
                    {"noise", out.noise},
                    {"texture_unlit", ToJson(out.texture)},
                    {"albedo_ambient", ToJson(out.ambient)}};
  if (out.truth) report["mean"]["against_truth"] = ToJson(*out.truth);
  WriteTextFileAtomically(dir / "holdout.json", report.dump(1) + "\n");
  return out;
}

}  // namespace genscene::apps
