// Distance to the synthetic part's true surface (see surface_distance.hpp).
#include "tools/synth/surface_distance.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace photomill::synth {

double distance_to_surface(const HeightField& h, const Eigen::Vector3d& c, double within_mm) {
  auto H = [&](double x, double y) { return h.contains(x, y) || (h.walled() && x >= h.x_min_mm && x <= h.x_max_mm &&
                                                                   y >= h.y_min_mm && y <= h.y_max_mm)
                                                ? h.height_mm(x, y)
                                                : 0.0; };
  double d = std::abs(c.z() - H(c.x(), c.y()));
  if (d <= within_mm) return d;
  // The nearest point of the graph is no farther than d in x, y either.
  const double reach = std::min(kPointReachMm, d);
  for (double dx = -reach; dx <= reach; dx += kPointGridMm) {
    for (double dy = -reach; dy <= reach; dy += kPointGridMm) {
      const double x = c.x() + dx, y = c.y() + dy;
      d = std::min(d, std::sqrt(dx * dx + dy * dy + (c.z() - H(x, y)) * (c.z() - H(x, y))));
    }
  }
  if (h.walled()) {
    // A face x = x0, y in [y_min, y_max], z in [0, f(x0, y)]: the top at the wall varies along
    // it, so its nearest point is sampled along y (same grid) with z clamped.
    for (const bool along_x : {false, true}) {
      const double lo = along_x ? h.x_min_mm : h.y_min_mm, hi = along_x ? h.x_max_mm : h.y_max_mm;
      for (const double at : along_x ? std::vector<double>{h.y_min_mm, h.y_max_mm} : std::vector<double>{h.x_min_mm, h.x_max_mm}) {
        const double across = (along_x ? c.y() : c.x()) - at;
        if (std::abs(across) >= d) continue;
        const double centre = along_x ? c.x() : c.y();
        for (double s = std::max(lo, centre - reach); s <= std::min(hi, centre + reach); s += kPointGridMm / 2) {
          const double top = along_x ? h.wall_top_mm(s, at) : h.wall_top_mm(at, s);
          const double dz = c.z() < 0 ? -c.z() : std::max(0.0, c.z() - top);
          d = std::min(d, std::sqrt(across * across + (centre - s) * (centre - s) + dz * dz));
        }
      }
    }
  }
  return d;
}

}  // namespace photomill::synth
