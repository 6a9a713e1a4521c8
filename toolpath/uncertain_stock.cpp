#include "toolpath/uncertain_stock.hpp"

#include <algorithm>
#include <cmath>

#include "formats/bspline.hpp"
#include "formats/error.hpp"

namespace photomill::toolpath {
namespace {

// Greville abscissa of pole i: the mean of its degree knots after the first.
double greville(const std::vector<double>& knots, int degree, int i) {
  double s = 0;
  for (int a = 1; a <= degree; ++a) s += knots[static_cast<std::size_t>(i + a)];
  return degree > 0 ? s / degree : knots[static_cast<std::size_t>(i)];
}

}  // namespace

BSplineSurface offset_by_uncertainty(const BSplineSurface& surface, const UncertaintyGrid& grid, double k,
                                     double threshold_mm, UncertainStockStats* stats) {
  if (!(k >= 0) || !std::isfinite(k)) throw UsageError("--stock-sigma-k must be a finite number >= 0");
  UncertainStockStats st;
  st.k = k;
  st.threshold_mm = threshold_mm;
  for (double s : grid.sigma_mm) {
    st.sigma_max_mm = std::max(st.sigma_max_mm, s);
    if (k * s > threshold_mm) st.area_mm2 += grid.step_mm * grid.step_mm;
  }
  BSplineSurface out = surface;
  double sum = 0;
  for (int i = 0; i < surface.num_poles_u; ++i) {
    const double u = greville(surface.knots_u, surface.degree_u, i);
    for (int j = 0; j < surface.num_poles_v; ++j) {
      const Eigen::Vector3d at = surface_point(surface, u, greville(surface.knots_v, surface.degree_v, j));
      const double raise = k * grid.max_within(at.x(), at.y(), 0);
      out.pole(i, j).z() += raise;
      sum += raise;
      st.max_mm = std::max(st.max_mm, raise);
    }
  }
  st.mean_mm = sum / static_cast<double>(std::max<std::size_t>(1, surface.poles_mm.size()));
  if (stats != nullptr) *stats = st;
  return out;
}

}  // namespace photomill::toolpath
