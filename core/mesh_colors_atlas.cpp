#include "core/mesh_colors_atlas.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include "core/check.h"
#include "core/color.h"
#include "core/parallel.h"

namespace genscene {

namespace {

int CellSide(int r, int gutter) {
  return r + 2 * gutter + 3;
}

// The faces of each resolution, largest first, two by two (the second -1 for a lone face).
std::vector<std::pair<int, int>> PairFaces(const std::vector<int>& resolution) {
  std::map<int, std::vector<int>, std::greater<int>> by_resolution;
  for (int f = 0; f < static_cast<int>(resolution.size()); ++f) {
    by_resolution[resolution[f]].push_back(f);
  }
  std::vector<std::pair<int, int>> cells;
  for (const auto& [r, faces] : by_resolution) {
    for (size_t k = 0; k < faces.size(); k += 2) {
      cells.emplace_back(faces[k], k + 1 < faces.size() ? faces[k + 1] : -1);
    }
  }
  return cells;
}

// Packs the cells into rows of `width` texels; returns the height the rows need and fills the
// layout's origins and steps.
long long PackRows(const std::vector<std::pair<int, int>>& cells, int width, int gutter,
                   AtlasLayout* layout) {
  long long x = 0, y = 0, row_height = 0;
  for (const auto& [a, b] : cells) {
    const int side = CellSide(layout->resolution[a], gutter);
    if (x + side > width) {
      y += row_height;
      x = 0;
      row_height = 0;
    }
    if (row_height == 0) row_height = side;  // rows start with their largest cell
    const int cx = static_cast<int>(x), cy = static_cast<int>(std::min<long long>(y, 1 << 30));
    layout->origin[a] = {cx + gutter, cy + gutter};
    layout->step[a] = 1;
    if (b >= 0) {
      layout->origin[b] = {cx + side - 1 - gutter, cy + side - 1 - gutter};
      layout->step[b] = -1;
    }
    x += side;
  }
  return y + row_height;
}

// Packs at the layout's resolutions: the smallest power-of-two width whose rows are no taller
// than wide, else the smallest whose rows fit max_size. False when none fits.
bool Pack(const AtlasOptions& options, AtlasLayout* layout) {
  const std::vector<std::pair<int, int>> cells = PairFaces(layout->resolution);
  double area = 0.0;
  int largest = 1;
  for (const auto& cell : cells) {
    const int side = CellSide(layout->resolution[cell.first], options.gutter);
    area += static_cast<double>(side) * side;
    largest = std::max(largest, side);
  }
  int width = 1;
  while (width < largest || static_cast<double>(width) * width < area) width *= 2;
  int fallback = 0;
  for (; width <= options.max_size; width *= 2) {
    const long long height = PackRows(cells, width, options.gutter, layout);
    if (height <= options.max_size && fallback == 0) fallback = width;
    if (height <= width) break;
  }
  if (width > options.max_size) {
    if (fallback == 0) return false;
    width = fallback;
  }
  layout->width = width;
  layout->height = static_cast<int>(std::max(1LL, PackRows(cells, width, options.gutter, layout)));
  return true;
}

}  // namespace

Eigen::Vector2d AtlasLayout::TexelPosition(int face, double b1, double b2) const {
  const double scale = static_cast<double>(step[face]) * resolution[face];
  return origin[face].cast<double>() + scale * Eigen::Vector2d(b1, b2);
}

Eigen::Vector2f AtlasLayout::Uv(int face, double b1, double b2) const {
  const Eigen::Vector2d t = TexelPosition(face, b1, b2);
  return Eigen::Vector2f(static_cast<float>((t.x() + 0.5) / width),
                         static_cast<float>((t.y() + 0.5) / height));
}

std::vector<Eigen::Vector2f> AtlasLayout::CornerUvs() const {
  std::vector<Eigen::Vector2f> uv;
  uv.reserve(3 * resolution.size());
  for (int f = 0; f < num_faces(); ++f) {
    uv.push_back(Uv(f, 0.0, 0.0));
    uv.push_back(Uv(f, 1.0, 0.0));
    uv.push_back(Uv(f, 0.0, 1.0));
  }
  return uv;
}

AtlasLayout MakeAtlasLayout(const std::vector<int>& face_resolution, const AtlasOptions& options) {
  if (options.gutter < 1 || options.gutter > 64) {
    throw Error(Format("atlas gutter = ", options.gutter, " texels must be in [1, 64]"));
  }
  if (options.max_size < 16 || options.max_size > 65536) {
    throw Error(Format("atlas max size = ", options.max_size, " texels must be in [16, 65536]"));
  }
  for (size_t f = 0; f < face_resolution.size(); ++f) {
    const int r = face_resolution[f];
    if (r < 1 || r > MeshColors::kMaxResolution || (r & (r - 1)) != 0) {
      throw Error(Format("atlas: face ", f, " has resolution ", r,
                         " (must be a power of two in [1, ", MeshColors::kMaxResolution, "])"));
    }
  }
  AtlasLayout layout;
  const size_t n = face_resolution.size();
  layout.origin.assign(n, Eigen::Vector2i::Zero());
  layout.step.assign(n, 1);
  for (;; ++layout.downscale) {
    layout.resolution.resize(n);
    bool all_one = true;
    for (size_t f = 0; f < n; ++f) {
      layout.resolution[f] = std::max(1, face_resolution[f] >> layout.downscale);
      all_one = all_one && layout.resolution[f] == 1;
    }
    if (Pack(options, &layout)) break;
    if (all_one) {
      throw Error(Format("atlas: ", n, " faces do not fit a ", options.max_size, "x",
                         options.max_size, " texture even at one texel step per face edge"));
    }
  }
  if (layout.downscale > 0) {
    layout.warnings.push_back(
        Format("atlas: the Mesh Colors need more than ", options.max_size, "x", options.max_size,
               " texels; every face's resolution was halved ", layout.downscale, " time(s) to fit ",
               layout.width, "x", layout.height, " (texel density / ", 1 << layout.downscale, ")"));
    spdlog::warn("{}", layout.warnings.back());
  }
  return layout;
}

namespace {

enum TexelState : uint8_t { kEmpty = 0, kFilled = 1, kQueued = 2 };

// Fills every empty texel in waves of increasing distance to the filled ones: a texel of the
// next wave takes the mean of its 8-neighbours filled in earlier waves.
void Dilate(int width, int height, std::vector<uint8_t>& state,
            std::vector<Eigen::Vector3f>& color) {
  auto for_neighbours = [&](size_t t, auto&& body) {
    const int x = static_cast<int>(t % width), y = static_cast<int>(t / width);
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if ((dx || dy) && nx >= 0 && ny >= 0 && nx < width && ny < height) {
          body(static_cast<size_t>(ny) * width + nx);
        }
      }
    }
  };
  std::vector<size_t> frontier, next;
  for (size_t t = 0; t < state.size(); ++t) {
    if (state[t] == kFilled) frontier.push_back(t);
  }
  while (!frontier.empty()) {
    next.clear();
    for (size_t t : frontier) {
      for_neighbours(t, [&](size_t n) {
        if (state[n] == kEmpty) {
          state[n] = kQueued;
          next.push_back(n);
        }
      });
    }
    ParallelFor(0, next.size(), [&](size_t k) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      for_neighbours(next[k], [&](size_t n) {
        if (state[n] == kFilled) sum += color[n], ++count;
      });
      color[next[k]] = sum / static_cast<float>(std::max(count, 1));
    });
    for (size_t t : next) state[t] = kFilled;
    frontier.swap(next);
  }
}

}  // namespace

AtlasImage BakeAtlas(const AtlasLayout& layout, const MeshColors& colors) {
  if (layout.num_faces() != colors.num_faces()) {
    throw Error(Format("atlas: the layout has ", layout.num_faces(), " faces, the Mesh Colors ",
                       colors.num_faces()));
  }
  AtlasImage image;
  image.width = layout.width;
  image.height = layout.height;
  const size_t count = static_cast<size_t>(layout.width) * layout.height;
  image.linear.assign(count, Eigen::Vector3f::Zero());
  std::vector<uint8_t> state(count, kEmpty);
  // Charts are disjoint, so faces write distinct texels.
  ParallelFor(
      0, static_cast<size_t>(layout.num_faces()),
      [&](size_t face) {
        const int f = static_cast<int>(face), r = layout.resolution[f], s = layout.step[f];
        const Eigen::Vector2i o = layout.origin[f];
        auto texel = [&](int i, int j) {
          return static_cast<size_t>(o.y() + s * j) * layout.width + (o.x() + s * i);
        };
        for (int j = 0; j <= r; ++j) {
          for (int i = 0; i + j <= r; ++i) {
            const size_t t = texel(i, j);
            image.linear[t] =
                colors.Linear(f, static_cast<float>(i) / r, static_cast<float>(j) / r);
            state[t] = kFilled;
          }
        }
        for (int i = 1; i <= r; ++i) {  // the ring past the long edge, i + j = r + 1
          const int j = r + 1 - i;
          const Eigen::Vector3f c = image.linear[texel(i, j - 1)] + image.linear[texel(i - 1, j)] -
                                    image.linear[texel(i - 1, j - 1)];
          image.linear[texel(i, j)] = c;
          state[texel(i, j)] = kFilled;
        }
      },
      16);
  Dilate(layout.width, layout.height, state, image.linear);
  image.srgb8.resize(3 * count);
  ParallelFor(0, count, [&](size_t t) {
    for (int c = 0; c < 3; ++c) {
      const float v = LinearToSrgb(std::clamp(image.linear[t][c], 0.0f, 1.0f));
      image.srgb8[3 * t + c] = static_cast<uint8_t>(std::lround(255.0f * v));
    }
  });
  return image;
}

}  // namespace genscene
