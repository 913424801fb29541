#include "apps/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::apps {

namespace {

// Tick values over [lo, hi]: 1-2-5 steps (linear), or powers of ten (log).
std::vector<double> Ticks(double lo, double hi, bool log) {
  std::vector<double> ticks;
  if (log) {  // powers of ten, with 2 and 5 times them when the range spans less than two decades
    for (double m : {1.0, 2.0, 5.0}) {
      if (m > 1.0 && ticks.size() >= 3) break;
      for (double e = std::floor(lo); e <= std::ceil(hi); e += 1.0) {
        const double t = e + std::log10(m);
        if (t >= lo - 1e-9 && t <= hi + 1e-9) ticks.push_back(t);
      }
    }
    std::sort(ticks.begin(), ticks.end());
    if (ticks.size() >= 2) return ticks;
    ticks.clear();
  }
  const double raw = (hi - lo) / 5.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw) {
      step = m * magnitude;
      break;
    }
  }
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step) ticks.push_back(t);
  return ticks;
}

std::string Label(double value, bool log) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3g", log ? std::pow(10.0, value) : value);
  return text;
}

}  // namespace

void WritePlot(const std::filesystem::path& png, const PlotSpec& spec,
               const std::vector<PlotSeries>& series) {
  const auto tx = [&](double v) { return spec.log_x ? std::log10(v) : v; };
  const auto ty = [&](double v) { return spec.log_y ? std::log10(v) : v; };
  const auto usable = [&](double x, double y) {
    return std::isfinite(x) && std::isfinite(y) && (!spec.log_x || x > 0.0) &&
           (!spec.log_y || y > 0.0);
  };
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!usable(s.x[i], s.y[i])) continue;
      x0 = std::min(x0, tx(s.x[i])), x1 = std::max(x1, tx(s.x[i]));
      y0 = std::min(y0, ty(s.y[i])), y1 = std::max(y1, ty(s.y[i]));
    }
  }
  if (!(x0 <= x1)) throw Error(Format(png.string(), ": nothing to plot for '", spec.title, "'"));
  if (x1 - x0 < 1e-12) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-12 * std::max(1.0, std::abs(y0)))
    y0 -= std::max(0.5, std::abs(y0) * 0.1), y1 += std::max(0.5, std::abs(y1) * 0.1);
  if (!spec.log_y && y0 > 0.0 && y0 < 0.5 * y1) y0 = 0.0;  // show the zero when it is near
  const double pad_y = 0.05 * (y1 - y0);
  y1 += pad_y;
  if (y0 != 0.0) y0 -= pad_y;

  cv::Mat image(spec.height, spec.width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 70, right = spec.width - 20, top = 40, bottom = spec.height - 50;
  const auto px = [&](double v) {
    return cv::Point(static_cast<int>(std::lround(left + (v - x0) / (x1 - x0) * (right - left))),
                     0);
  };
  const auto py = [&](double v) {
    return static_cast<int>(std::lround(bottom - (v - y0) / (y1 - y0) * (bottom - top)));
  };
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  for (double t : Ticks(x0, x1, spec.log_x)) {
    const int x = px(t).x;
    cv::line(image, {x, top}, {x, bottom}, grid, 1);
    const std::string label = Label(t, spec.log_x);
    cv::putText(image, label, {x - 4 * static_cast<int>(label.size()), bottom + 16}, font, 0.4,
                black, 1, cv::LINE_AA);
  }
  for (double t : Ticks(y0, y1, spec.log_y)) {
    const int y = py(t);
    cv::line(image, {left, y}, {right, y}, grid, 1);
    const std::string label = Label(t, spec.log_y);
    cv::putText(image, label, {left - 8 - 7 * static_cast<int>(label.size()), y + 4}, font, 0.4,
                black, 1, cv::LINE_AA);
  }
  cv::rectangle(image, {left, top}, {right, bottom}, black, 1);
  cv::putText(image, spec.title, {left, 18}, font, 0.55, black, 1, cv::LINE_AA);
  cv::putText(image, spec.x_label,
              {(left + right) / 2 - 4 * static_cast<int>(spec.x_label.size()), spec.height - 12},
              font, 0.45, black, 1, cv::LINE_AA);
  cv::putText(image, spec.y_label, {8, top - 6}, font, 0.4, cv::Scalar(80, 80, 80), 1, cv::LINE_AA);

  static const cv::Scalar colours[] = {{180, 119, 31}, {14, 127, 255},  {44, 160, 44},
                                       {40, 39, 214},  {189, 103, 148}, {75, 86, 140}};
  int legend_y = top + 16;
  for (size_t k = 0; k < series.size(); ++k) {
    const cv::Scalar colour = colours[k % 6];
    std::vector<cv::Point> points;
    const PlotSeries& s = series[k];
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (usable(s.x[i], s.y[i])) points.push_back({px(tx(s.x[i])).x, py(ty(s.y[i]))});
    }
    if (points.size() > 1) cv::polylines(image, points, false, colour, 2, cv::LINE_AA);
    for (const cv::Point& p : points) cv::circle(image, p, 3, colour, cv::FILLED, cv::LINE_AA);
    if (!s.name.empty()) {  // right-aligned inside the frame, on a white box
      int baseline = 0;
      const cv::Size text = cv::getTextSize(s.name, font, 0.4, 1, &baseline);
      const int x = right - 8 - text.width;
      cv::rectangle(image, {x - 30, legend_y - text.height - 3}, {right - 2, legend_y + 4},
                    cv::Scalar(255, 255, 255), cv::FILLED);
      cv::line(image, {x - 26, legend_y - 4}, {x - 6, legend_y - 4}, colour, 2, cv::LINE_AA);
      cv::putText(image, s.name, {x, legend_y}, font, 0.4, black, 1, cv::LINE_AA);
      legend_y += 16;
    }
  }
  std::vector<uchar> bytes;
  if (!cv::imencode(".png", image, bytes))
    throw Error(Format(png.string(), ": cannot encode the plot"));
  WriteFileAtomically(png, [&](const std::filesystem::path& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() ||
        std::fclose(f) != 0) {
      throw Error(Format(png.string(), ": cannot write the plot"));
    }
  });
}

}  // namespace genscene::apps
