// Albedo of the plate, the part and the ChArUco board, box-filtered (see texture.hpp).
#include "tools/synth/texture.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>

#include "tools/synth/random.hpp"

namespace photomill::synth {
namespace {

// The footprint is capped at this many cells: beyond it supersampling does the averaging.
constexpr double kMaxFootprintCells = 3.0;

// Average of cell_value over the square [a - w/2, a + w/2] x [b - w/2, b + w/2] in a grid of unit
// cells (cell (i, j) = [i, i+1) x [j, j+1)). w <= 0 point-samples.
template <typename CellValue>
double box_filter(double a, double b, double w, const CellValue& cell_value) {
  if (!(w > 1e-9)) {
    return cell_value(static_cast<int>(std::floor(a)), static_cast<int>(std::floor(b)));
  }
  w = std::min(w, kMaxFootprintCells);
  const double a0 = a - w / 2, a1 = a + w / 2, b0 = b - w / 2, b1 = b + w / 2;
  const int i0 = static_cast<int>(std::floor(a0)), i1 = static_cast<int>(std::floor(a1));
  const int j0 = static_cast<int>(std::floor(b0)), j1 = static_cast<int>(std::floor(b1));
  double sum = 0;
  for (int i = i0; i <= i1; ++i) {
    const double ox = std::min(a1, i + 1.0) - std::max(a0, static_cast<double>(i));
    if (ox <= 0) continue;
    for (int j = j0; j <= j1; ++j) {
      const double oy = std::min(b1, j + 1.0) - std::max(b0, static_cast<double>(j));
      if (oy <= 0) continue;
      sum += ox * oy * cell_value(i, j);
    }
  }
  return sum / (w * w);
}

double quintic(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

double lattice(std::int64_t ix, std::int64_t iy, std::uint64_t seed) {
  const std::uint64_t h = splitmix64(seed ^ splitmix64(static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ull ^
                                                       static_cast<std::uint64_t>(iy) * 0xC2B2AE3D27D4EB4Full));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

}  // namespace

double value_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const double tx = quintic(x - fx), ty = quintic(y - fy);
  const double v00 = lattice(ix, iy, seed), v10 = lattice(ix + 1, iy, seed);
  const double v01 = lattice(ix, iy + 1, seed), v11 = lattice(ix + 1, iy + 1, seed);
  return (v00 + (v10 - v00) * tx) + ((v01 + (v11 - v01) * tx) - (v00 + (v10 - v00) * tx)) * ty;
}

MarkerBits marker_bits(const std::string& dictionary, int id) {
  const auto dict = cv::aruco::getPredefinedDictionary(dictionary_id(dictionary));
  MarkerBits bits;
  bits.cells = dict->markerSize + 2;
  cv::Mat img;
  cv::aruco::drawMarker(dict, id, bits.cells, img, 1);
  if (img.rows != bits.cells || img.cols != bits.cells || img.type() != CV_8UC1) {
    throw std::runtime_error("cv::aruco::drawMarker returned an unexpected image");
  }
  bits.white.resize(static_cast<std::size_t>(bits.cells) * bits.cells);
  for (int r = 0; r < bits.cells; ++r) {
    for (int c = 0; c < bits.cells; ++c) bits.white[r * bits.cells + c] = img.at<std::uint8_t>(r, c) > 127;
  }
  return bits;
}

PartTexture::PartTexture(const PartScene& scene, Palette palette)
    : scene_(scene), palette_(palette) {
  for (const Marker& m : scene.markers) {
    Placed p{&m, marker_bits(scene.dictionary, m.id), 0, 0, 0, 0, 0};
    p.cell_mm = m.size_mm / p.bits.cells;
    const double q = scene.quiet_zone_cells * p.cell_mm;
    p.x0 = m.top_left_mm.x() - q;
    p.x1 = m.top_left_mm.x() + m.size_mm + q;
    p.y0 = m.top_left_mm.y() - m.size_mm - q;
    p.y1 = m.top_left_mm.y() + q;
    markers_.push_back(std::move(p));
  }
  grid_nx_ = static_cast<int>(std::ceil((scene.plate_x_max_mm - scene.plate_x_min_mm) / grid_mm_));
  grid_ny_ = static_cast<int>(std::ceil((scene.plate_y_max_mm - scene.plate_y_min_mm) / grid_mm_));
  grid_.resize(static_cast<std::size_t>(grid_nx_) * grid_ny_);
  for (int k = 0; k < static_cast<int>(markers_.size()); ++k) {
    const Placed& p = markers_[k];
    const int i0 = std::max(0, static_cast<int>(std::floor((p.x0 - scene.plate_x_min_mm) / grid_mm_)));
    const int i1 = std::min(grid_nx_ - 1, static_cast<int>(std::floor((p.x1 - scene.plate_x_min_mm) / grid_mm_)));
    const int j0 = std::max(0, static_cast<int>(std::floor((p.y0 - scene.plate_y_min_mm) / grid_mm_)));
    const int j1 = std::min(grid_ny_ - 1, static_cast<int>(std::floor((p.y1 - scene.plate_y_min_mm) / grid_mm_)));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) grid_[static_cast<std::size_t>(j) * grid_nx_ + i].push_back(k);
    }
  }
}

// Two octaves of value noise pushed through a steep contrast curve: dark and light blobs of about
// the grain size, as a DIC speckle pattern. Fades to its mean where the footprint is larger than
// the grain (it would alias).
double PartTexture::speckle(double x, double y, double footprint_mm) const {
  const double g = scene_.speckle_mm;
  const double n = 0.65 * value_noise(x / g, y / g, scene_.speckle_seed) +
                   0.35 * value_noise(2 * x / g + 17.31, 2 * y / g + 5.17, scene_.speckle_seed + 1);
  double t = std::clamp(0.5 + (n - 0.5) * 3.5, 0.0, 1.0);
  t = t * t * (3 - 2 * t);
  const double mean = 0.5 * (palette_.speckle_dark + palette_.speckle_light);
  const double v = palette_.speckle_dark + (palette_.speckle_light - palette_.speckle_dark) * t;
  const double fade = std::clamp((footprint_mm / g - 0.5) / 1.0, 0.0, 1.0);
  return v + (mean - v) * fade;
}

double PartTexture::albedo(double x, double y, double footprint_mm) const {
  const PartScene& s = scene_;
  if (x < s.plate_x_min_mm || x > s.plate_x_max_mm || y < s.plate_y_min_mm || y > s.plate_y_max_mm) {
    return palette_.table * (0.85 + 0.3 * value_noise(x / 25, y / 25, s.speckle_seed + 7));
  }
  const int i = std::min(grid_nx_ - 1, static_cast<int>((x - s.plate_x_min_mm) / grid_mm_));
  const int j = std::min(grid_ny_ - 1, static_cast<int>((y - s.plate_y_min_mm) / grid_mm_));
  for (int k : grid_[static_cast<std::size_t>(j) * grid_nx_ + i]) {
    const Placed& p = markers_[k];
    if (x < p.x0 || x > p.x1 || y < p.y0 || y > p.y1) continue;
    // Cell coordinates from corner 0: a to the right, b downwards.
    const double a = (x - p.marker->top_left_mm.x()) / p.cell_mm;
    const double b = (p.marker->top_left_mm.y() - y) / p.cell_mm;
    const int n = p.bits.cells;
    return box_filter(a, b, footprint_mm / p.cell_mm, [&](int ci, int cj) {
      if (ci < 0 || cj < 0 || ci >= n || cj >= n) return palette_.white;
      return p.bits.white[cj * n + ci] ? palette_.white : palette_.black;
    });
  }
  return speckle(x, y, footprint_mm);
}

double PartTexture::wall_albedo(double along_mm, double z_mm, double footprint_mm) const {
  return speckle(along_mm, z_mm + 5000, footprint_mm);
}

BoardTexture::BoardTexture(const BoardSpec& spec, Palette palette) : spec_(spec), palette_(palette) {
  validate(spec);
  const auto dict = cv::aruco::getPredefinedDictionary(dictionary_id(spec.dictionary));
  const auto board =
      cv::aruco::CharucoBoard::create(spec.squares_x, spec.squares_y, static_cast<float>(spec.square_mm),
                                      static_cast<float>(spec.marker_mm), dict);
  squares_.assign(static_cast<std::size_t>(spec.squares_x) * spec.squares_y, Square{});
  for (std::size_t k = 0; k < board->ids.size(); ++k) {
    const auto& c = board->objPoints[k];
    BoardMarker m;
    m.bits = marker_bits(spec.dictionary, board->ids[k]);
    m.origin = {c[0].x, c[0].y};
    const Eigen::Vector2d e1 = Eigen::Vector2d(c[1].x, c[1].y) - m.origin;
    const Eigen::Vector2d e3 = Eigen::Vector2d(c[3].x, c[3].y) - m.origin;
    m.ex = e1.normalized();
    m.ey = e3.normalized();
    m.cell_mm = e1.norm() / m.bits.cells;
    // Corner order 0 -> 1 -> 3 reads the marker unmirrored from the side opposite e1 x e3.
    printed_side_ = e1.x() * e3.y() - e1.y() * e3.x() > 0 ? -1.0 : 1.0;
    const Eigen::Vector2d centre = m.origin + 0.5 * (e1 + e3);
    const int i = static_cast<int>(std::floor(centre.x() / spec.square_mm));
    const int j = static_cast<int>(std::floor(centre.y() / spec.square_mm));
    if (i < 0 || j < 0 || i >= spec.squares_x || j >= spec.squares_y) {
      throw std::runtime_error("ChArUco marker outside the board");
    }
    squares_[static_cast<std::size_t>(j) * spec.squares_x + i].marker = static_cast<int>(markers_.size());
    markers_.push_back(std::move(m));
  }
  for (std::size_t k = 0; k < board->chessboardCorners.size(); ++k) {
    const auto& p = board->chessboardCorners[k];
    ControlPoint cp;
    cp.point_id = static_cast<PointId>(k);
    cp.xyz_mm = {p.x, p.y, p.z};
    corners_.push_back(cp);
  }
}

double BoardTexture::square_value(int i, int j, double x, double y, double footprint_mm) const {
  if (i < 0 || j < 0 || i >= spec_.squares_x || j >= spec_.squares_y) return palette_.white;
  const Square& sq = squares_[static_cast<std::size_t>(j) * spec_.squares_x + i];
  if (sq.marker < 0) return palette_.black;
  const BoardMarker& m = markers_[sq.marker];
  const Eigen::Vector2d d = Eigen::Vector2d(x, y) - m.origin;
  const double a = d.dot(m.ex) / m.cell_mm;
  const double b = d.dot(m.ey) / m.cell_mm;
  const int n = m.bits.cells;
  return box_filter(a, b, footprint_mm / m.cell_mm, [&](int ci, int cj) {
    if (ci < 0 || cj < 0 || ci >= n || cj >= n) return palette_.white;
    return m.bits.white[cj * n + ci] ? palette_.white : palette_.black;
  });
}

double BoardTexture::albedo(double x, double y, double footprint_mm) const {
  if (x < x_min() || x > x_max() || y < y_min() || y > y_max()) {
    return palette_.table * (0.85 + 0.3 * value_noise(x / 25, y / 25, 99));
  }
  const double s = spec_.square_mm;
  // Squares are box-filtered as cells; inside a white square the marker is filtered on its own
  // grid (the marker never comes closer than (s - m)/2 to the square's edge, far more than a
  // footprint, so the two filters never interact).
  return box_filter(x / s, y / s, footprint_mm / s, [&](int i, int j) {
    const double cx = std::clamp(x, i * s, (i + 1) * s);
    const double cy = std::clamp(y, j * s, (j + 1) * s);
    return square_value(i, j, cx, cy, footprint_mm);
  });
}

}  // namespace photomill::synth
