// fitsurf_bench: speed and accuracy figures of fitsurf's method on the analytic test shapes
// (fitsurf/test_shapes.hpp), printed as a table for docs/measurements/fitsurf.md. Not a test: it asserts
// nothing; scripts/bench-fitsurf.sh runs it with the machine load alongside.
//   fitsurf_bench [--threads N] [--repeat R] [--quick] [--section speed|accuracy|outliers|robust|sparse|layouts|synth]
//   fitsurf_bench --write-cloud FILE.ply|FILE.xyz [--points N] [--shape NAME]   (input for CLI timing)
//   fitsurf_bench --truth SAMPLES.xyz [--shape NAME]   (deviation of surface samples from the truth,
//                                                      for scripts/bench-fitsurf-freecad.sh)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "fitsurf/fit.hpp"
#include "fitsurf/fitsurf.hpp"
#include "fitsurf/outline.hpp"
#include "geometry/parallel.hpp"
#include "fitsurf/report.hpp"
#include "fitsurf/synth_shapes.hpp"
#include "fitsurf/test_shapes.hpp"
#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/point_cloud.hpp"
#include "tools/synth/height_field.hpp"

namespace {

using namespace photomill;
using namespace photomill::fitsurf;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Times {
  std::vector<double> wall, cpu;  // seconds, sorted
};

// Wall time and process CPU time (all threads) of each run: with other work on the machine the
// wall time grows, the CPU time much less.
template <typename F>
Times timed(int repeat, F&& f) {
  Times t;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = Clock::now();
    const std::clock_t c0 = std::clock();
    f();
    t.cpu.push_back(static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
    t.wall.push_back(seconds_since(t0));
  }
  std::sort(t.wall.begin(), t.wall.end());
  std::sort(t.cpu.begin(), t.cpu.end());
  return t;
}

void print_times(const char* what, const Times& t) {
  std::printf("%-60s wall min %.3f s median %.3f s | cpu median %.3f s (%zu runs)\n", what, t.wall.front(),
              t.wall[t.wall.size() / 2], t.cpu[t.cpu.size() / 2], t.wall.size());
}

using test::cloud_of;

test::TruthDeviation truth(const FitResult& fit, const test::Shape& s) { return test::truth_inside_outline(fit.surface, s, 150); }

}  // namespace

int main(int argc, char** argv) {
  int threads = 0, repeat = 3;
  bool quick = false;
  std::string write_cloud, truth_samples, shape_name = "bumps", only;
  std::size_t points = 100000;
  for (int k = 1; k < argc; ++k) {
    if (!std::strcmp(argv[k], "--threads") && k + 1 < argc) threads = std::atoi(argv[++k]);
    else if (!std::strcmp(argv[k], "--repeat") && k + 1 < argc) repeat = std::max(1, std::atoi(argv[++k]));
    else if (!std::strcmp(argv[k], "--quick")) quick = true;
    else if (!std::strcmp(argv[k], "--write-cloud") && k + 1 < argc) write_cloud = argv[++k];
    else if (!std::strcmp(argv[k], "--section") && k + 1 < argc) only = argv[++k];
    else if (!std::strcmp(argv[k], "--truth") && k + 1 < argc) truth_samples = argv[++k];
    else if (!std::strcmp(argv[k], "--points") && k + 1 < argc) points = std::strtoull(argv[++k], nullptr, 10);
    else if (!std::strcmp(argv[k], "--shape") && k + 1 < argc) shape_name = argv[++k];
    else {
      std::fprintf(stderr,
                   "usage: fitsurf_bench [--threads N] [--repeat R] [--quick] [--section speed|accuracy|outliers|robust|sparse|layouts|synth]\n"
                   "       fitsurf_bench --write-cloud FILE.ply|FILE.xyz [--points N] [--shape NAME]\n"
                   "       fitsurf_bench --truth SAMPLES.xyz [--shape NAME]\n");
      return 2;
    }
  }
  if (!write_cloud.empty()) {
    // 0.01 mm noise, like the figures below.
    const PointCloud cloud = cloud_of(test::sample(test::shape(shape_name), points, 0.01, 7));
    std::ofstream out(write_cloud, std::ios::binary);
    if (write_cloud.size() > 4 && write_cloud.substr(write_cloud.size() - 4) == ".ply") {
      write_ply(out, cloud, PlyEncoding::BinaryLittleEndian);
    } else {
      write_xyz(out, cloud);
    }
    return out ? 0 : 1;
  }
  if (!truth_samples.empty()) {
    // Points sampled on a fitted surface (by any program): their distance to the true shape,
    // over the samples whose (x, y) lies inside the sampled rectangle (the data's extent; a
    // surface's extrapolation beyond it is not judged). Prints "count rms_mm max_mm".
    std::ifstream in(truth_samples);
    const PointCloud c = read_xyz(in, truth_samples);
    const test::Shape s = test::shape(shape_name);
    double sum2 = 0, max_mm = 0;
    std::size_t n = 0;
    for (const auto& p : c.points_mm) {
      if (p.x() < test::kXMin || p.x() > test::kXMax || p.y() < test::kYMin || p.y() > test::kYMax) continue;
      const double d = test::distance_to_truth(s, p);
      sum2 += d * d;
      max_mm = std::max(max_mm, d);
      ++n;
    }
    std::printf("%zu %.5f %.5f\n", n, n ? std::sqrt(sum2 / static_cast<double>(n)) : 0.0, max_mm);
    return n ? 0 : 1;
  }
  const auto want = [&](const char* section) { return only.empty() || only == section; };
  log::set_level(log::Level::Quiet);
  std::printf("fitsurf_bench: %d worker threads (hardware: %d)\n\n", geometry::thread_count(threads), geometry::thread_count(0));

  // Speed 1: 1 000 000 points, 40x40 cubic, one pass (no parameter correction, no reweighting).
  if (want("speed")) {
    const auto pts = test::sample(test::shape("bumps"), quick ? 200000 : 1000000, 0.01, 1);
    FitOptions o;
    o.poles_u = o.poles_v = 40;
    o.parameter_correction = false;
    o.robust = RobustLoss::None;
    o.max_rounds = 1;
    o.threads = threads;
    o.final_projection = false;
    FitResult fit;
    print_times(quick ? "200k points, 40x40, one pass (fit only)" : "1M points, 40x40, one pass (fit only)",
                timed(repeat, [&] { fit = fit_surface(pts, o); }));
    o.final_projection = true;
    print_times("  same + orthogonal residuals of every point (foot points)", timed(repeat, [&] { fit = fit_surface(pts, o); }));
    std::printf("  deviation from truth: RMS %.5f mm, max %.5f mm\n", truth(fit, test::shape("bumps")).rms_mm,
                truth(fit, test::shape("bumps")).max_mm);
  }
  // Speed 2: the whole default fit of 100 000 points (fitsurf's defaults: 30x30, parameter
  // correction, outline, fold check, statistics).
  if (want("speed")) {
    const PointCloud cloud = cloud_of(test::sample(test::shape("bumps"), 100000, 0.01, 2));
    Options o;
    o.fit.threads = threads;
    Result r;
    print_times("100k points, default fit (30x30, correction, outline)",
                timed(repeat, [&] { r = fit_point_cloud(cloud, o); }));
    std::printf("  rounds %zu, residual RMS %.5f mm\n", r.fit.round_rms_mm.size(), r.stats.rms_mm);
  }
  if (quick) return 0;

  // Accuracy: 100 000 points, noise 0.01 mm: plane projection alone and with parameter
  // correction, at 30x30 (the done-when net) on every shape, and at coarser nets, where the net
  // rather than the noise limits the accuracy, on the most curved (steep) and steepest (ridge).
  if (want("accuracy")) {
  std::printf("\n%-8s %-6s %-22s %10s %10s %10s %7s %7s\n", "shape", "net", "method", "truth RMS", "truth max",
              "resid RMS", "rounds", "wall s");
  struct Case {
    std::string shape;
    int net;
  };
  std::vector<Case> cases;
  for (const auto& s : test::shapes()) cases.push_back({s.name, 30});
  for (int net : {12, 16, 20}) {
    cases.push_back({"steep", net});
    cases.push_back({"ridge", net});
  }
  for (const Case& c : cases) {
    const test::Shape s = test::shape(c.shape);
    const PointCloud cloud = cloud_of(test::sample(s, 100000, 0.01, 3));
    for (bool correction : {false, true}) {
      Options o;
      o.fit.threads = threads;
      o.fit.poles_u = o.fit.poles_v = c.net;
      o.fit.parameter_correction = correction;
      o.fit.robust = RobustLoss::None;  // the parameterisations alone (reweighting: --section robust)
      const auto t0 = Clock::now();
      const Result r = fit_point_cloud(cloud, o);
      const double t = seconds_since(t0);
      const auto dev = truth(r.fit, s);
      std::printf("%-8s %-6s %-22s %10.5f %10.5f %10.5f %7zu %7.3f\n", s.name.c_str(),
                  (std::to_string(c.net) + "x" + std::to_string(c.net)).c_str(),
                  correction ? "plane + correction" : "plane projection only", dev.rms_mm, dev.max_mm, r.stats.rms_mm,
                  r.fit.round_rms_mm.size(), t);
    }
  }
  }
  // Outliers: 2 % of 100 000 points 0.5-5 mm off the surface; robust reweighting.
  if (want("outliers")) {
    const test::Shape s = test::shape("bumps");
    auto pts = test::sample(s, 100000, 0.01, 25);
    test::Rng rng(26);
    for (std::size_t k = 0; k < pts.size(); k += 50) pts[k].z() += (k % 100 ? 1 : -1) * rng.uniform(0.5, 5.0);
    const PointCloud cloud = cloud_of(pts);
    std::printf("\n%-34s %10s %10s %9s %7s\n", "bumps, 2 % outliers, 30x30", "truth RMS", "truth max", "outliers",
                "rounds");
    for (RobustLoss loss : {RobustLoss::None, RobustLoss::Reject, RobustLoss::Huber, RobustLoss::Tukey}) {
      Options o;
      o.fit.threads = threads;
      o.fit.robust = loss;
      o.fit.fold.max_slope_deg = 90;  // a plain fit curls at the edge: measure, do not refuse
      const Result r = fit_point_cloud(cloud, o);
      const auto dev = truth(r.fit, s);
      std::printf("%-34s %10.5f %10.5f %9zu %7zu\n",
                  ("--robust " + to_string(loss)).c_str(),
                  dev.rms_mm, dev.max_mm, r.fit.outliers, r.fit.round_rms_mm.size());
    }
  }
  if (want("robust")) {
  // Robust reweighting on or off by default: clean clouds and clouds with 1-5 % gross outliers
  // (mismatched features: 1-5 mm off the surface, either side), dense (100 000 points) and
  // SIFT-like (5 000 points), on bumps and the demo part; truth inside the outline.
  std::printf("\n%-6s %7s %9s %-8s %10s %10s %9s %10s %7s\n", "shape", "points", "outliers", "robust", "truth RMS",
              "truth max", "flagged", "resid RMS", "wall s");
  for (const char* name : {"bumps", "demo"}) {
    const test::Shape s = test::shape(name);
    for (std::size_t n : {std::size_t{100000}, std::size_t{5000}}) {
      for (double fraction : {0.0, 0.01, 0.05}) {
        auto pts = test::sample(s, n, 0.01, 31);
        test::Rng rng(32);
        std::size_t injected = 0;
        for (std::size_t k = 0; k < pts.size(); ++k) {
          if (rng.uniform() >= fraction) continue;
          pts[k].z() += (rng.uniform() < 0.5 ? -1 : 1) * rng.uniform(1.0, 5.0);
          ++injected;
        }
        const PointCloud cloud = cloud_of(pts);
        for (RobustLoss loss : {RobustLoss::None, RobustLoss::Reject, RobustLoss::Tukey}) {
          Options o;
          o.fit.threads = threads;
          o.fit.robust = loss;
          o.fit.fold.max_slope_deg = 90;  // measure, do not refuse
          const auto t0 = Clock::now();
          Result r;
          try {
            r = fit_point_cloud(cloud, o);
          } catch (const GeometryError&) {  // the surface curls over (outliers at the edge)
            std::printf("%-6s %7zu %9zu %-8s %10s %10s %9s %10s %7.3f\n", name, n, injected, to_string(loss).c_str(),
                        "folds", "-", "-", "-", seconds_since(t0));
            continue;
          }
          const double t = seconds_since(t0);
          const auto dev = truth(r.fit, s);
          std::printf("%-6s %7zu %9zu %-8s %10.5f %10.5f %9zu %10.5f %7.3f\n", name, n, injected, to_string(loss).c_str(),
                      dev.rms_mm, dev.max_mm, r.fit.outliers, r.stats.rms_mm, t);
        }
      }
    }
  }
  }
  if (want("sparse")) {
  // Sparse marker-like points: a jittered grid (15x10: 10 mm apart; 30x20: 5 mm), noise
  // 0.01 mm; the spline alone (--prefit none) with the default smoothing or --noise-mm 0.01, each
  // with smoothing order 2 (thin plate) and 3, and the kernel prefit (--prefit kernel, which is
  // fitsurf's default for the 150 points); deviation and curvature inside the points' hull.
  std::printf("\n%-6s %5s %-8s %6s %-16s %9s %10s %10s %9s %9s %6s %9s %s\n", "prefit", "order", "shape", "points", "smoothing",
              "lambda", "truth RMS", "truth max", "max curv", "true curv", "ratio", "TPS max", "kernel (LOO RMS mm), s");
  for (const auto& s : test::shapes()) {
    for (int nx : {15, 30}) {
      const PointCloud cloud = cloud_of(test::sample_grid(s, nx, nx * 2 / 3, 45.0 / nx, 0.01, 4));
      // The thin-plate spline interpolant of the same points. It passes through the same markers,
      // so no fit can be within half of its distance from the truth of both it and the truth: the
      // information limit.
      const auto tps = test::thin_plate_interpolant(cloud.points_mm);
      for (Prefit prefit : {Prefit::None, Prefit::Kernel}) {
      for (int order : {2, 3}) {
        for (double noise : {0.0, 0.01}) {
          // The kernel shapes the surface, not the order; it interpolates (no --noise-mm).
          if (prefit == Prefit::Kernel && (order == 3 || noise > 0)) continue;
          Options o;
          o.prefit.mode = prefit;
          o.fit.threads = threads;
          o.fit.smoothing_order = order;
          o.fit.noise_mm = noise;
          o.fit.fold.max_slope_deg = 90;  // report, do not refuse
          const Result r = fit_point_cloud(cloud, o);
          const auto dev = truth(r.fit, s);
          // The TPS interpolant's largest distance from the truth over the same (x, y) samples
          // inside this fit's outline.
          double tps_max = 0;
          const auto& b = r.fit.surface.boundary_uv;
          for (int a = 0; a < 150; ++a) {
            for (int c = 0; c < 150; ++c) {
              const Eigen::Vector2d uv((a + 0.5) / 150, (c + 0.5) / 150);
              if (!b.empty() && !point_in_polygon(b, uv)) continue;
              const Eigen::Vector3d x = surface_point(r.fit.surface, uv.x(), uv.y());
              tps_max = std::max(tps_max, test::distance_to_truth(s, Eigen::Vector3d(x.x(), x.y(), tps(x.x(), x.y()))));
            }
          }
          std::string kernel = "-";
          if (r.prefit) {
            char buf[128];
            const KernelModel& m = r.prefit->model;
            std::snprintf(buf, sizeof buf, "%s %.3g mm t%d a%.3g@%.3g (%.4f)", to_string(m.shape).c_str(), m.length_mm,
                          m.trend_degree, m.aspect, m.angle_deg, r.prefit->loo_rms_mm);
            kernel = buf;
          }
          std::printf("%-6s %5d %-8s %6zu %-16s %9.3g %10.5f %10.5f %9.5f %9.5f %6.2f %9.5f %s %.2f\n",
                      prefit == Prefit::Kernel ? "kernel" : "none", order, s.name.c_str(), cloud.points_mm.size(),
                      noise > 0 ? "--noise-mm 0.01" : "default", r.fit.smoothing_mm4, dev.rms_mm, dev.max_mm,
                      dev.max_curvature, dev.true_max_curvature, dev.max_curvature / dev.true_max_curvature, tps_max,
                      kernel.c_str(), r.seconds);
        }
      }
      }
    }
  }
  }
  if (want("layouts")) {
  // The sparse criterion over many marker layouts (seeds 1-24): 150 markers, default
  // options, the largest distance from the truth inside the points' hull, and the same at least
  // 2.5 mm inside it (a quarter of the spacing: away from the edge between two outer markers).
  // fitsurf's shapes with the markers over the whole rectangle; synth's parts with them over the
  // interior (where synth puts a part's markers) and over the whole part (the blend in the hull).
  constexpr int layouts = 24;
  std::printf("\n150 markers, default options, %d layouts each: max distance from the truth inside the hull, mm\n",
              layouts);
  std::printf("%-8s %-12s %8s %8s %8s %12s %10s %8s\n", "shape", "markers", "median", "worst", ">0.1", "worst>=2.5mm",
              "curv ratio", "s/fit");
  struct Case {
    test::Shape shape;
    const char* where;
    bool interior;
  };
  std::vector<Case> cases;
  for (const auto& s : test::shapes()) cases.push_back({s, "whole", false});
  for (const auto& name : synth::shape_names()) cases.push_back({test::synth_part(name), "synth inside", true});
  for (const auto& name : synth::shape_names()) cases.push_back({test::synth_part(name), "synth whole", false});
  for (const auto& c : cases) {
    std::vector<double> worst;
    double inner = 0, ratio = 0, seconds = 0;
    for (int seed = 1; seed <= layouts; ++seed) {
      const auto pts = c.interior ? test::synth_interior_markers(c.shape, static_cast<std::uint64_t>(seed))
                                  : test::sample_grid(c.shape, 15, 10, 3.0, 0.01, static_cast<std::uint64_t>(seed));
      std::vector<Eigen::Vector2d> xy;
      for (const auto& p : pts) xy.push_back(p.head<2>());
      const std::vector<Eigen::Vector2d> hull = convex_hull(xy);
      Options o;
      o.fit.threads = threads;
      o.fit.fold.max_slope_deg = 90;  // report, do not refuse
      const Result r = fit_point_cloud(cloud_of(pts), o);
      seconds += r.seconds;
      const BSplineSurface& surf = r.fit.surface;
      const auto dev = test::truth_inside_outline(surf, c.shape);
      worst.push_back(dev.max_mm);
      ratio = std::max(ratio, dev.max_curvature / dev.true_max_curvature);
      // The same (u,v) samples as truth_inside_outline's.
      constexpr int n = test::kTruthGrid;
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          const Eigen::Vector2d uv((a + 0.5) / n, (b + 0.5) / n);
          if (!surf.boundary_uv.empty() && !point_in_polygon(surf.boundary_uv, uv)) continue;
          const Eigen::Vector3d x = surface_point(surf, uv.x(), uv.y());
          const Eigen::Vector2d q = x.head<2>();
          if (!point_in_polygon(hull, q)) continue;
          if (boundary_distance(hull, q) >= 2.5) inner = std::max(inner, test::distance_to_truth(c.shape, x));
        }
      }
    }
    std::vector<double> sorted = worst;
    std::sort(sorted.begin(), sorted.end());
    const auto over = std::count_if(worst.begin(), worst.end(), [](double w) { return w > 0.1; });
    std::printf("%-8s %-12s %8.3f %8.3f %5td/%-2d %12.3f %10.2f %8.2f\n", c.shape.name.c_str(), c.where,
                sorted[sorted.size() / 2], sorted.back(), over, layouts, inner, ratio, seconds / layouts);
  }
  }
  if (want("synth")) {
  // Done-when 1 on synth's own parts: 100 000 points, 0.01 mm noise, uniform and adaptive knots.
  std::printf("\nsynth's parts, 100 000 points, 0.01 mm noise, --robust none: truth RMS / max mm (plane only -> corrected)\n");
  std::printf("%-8s %-8s %-9s %20s %20s %8s\n", "part", "net", "knots", "plane only", "corrected", "s");
  for (const auto& name : synth::shape_names()) {
    const test::Shape shape = test::synth_part(name);
    const PointCloud cloud = cloud_of(test::sample(shape, 100000, 0.01, 21));
    for (int net : {30, 40}) {
      for (KnotPlacement knots : {KnotPlacement::Uniform, KnotPlacement::Adaptive}) {
        if (net == 40 && knots == KnotPlacement::Adaptive) continue;
        test::TruthDeviation dev[2];
        double seconds = 0;
        for (int correct = 0; correct < 2; ++correct) {
          Options o;
          o.fit.poles_u = o.fit.poles_v = net;
          o.fit.knots = knots;
          o.fit.robust = RobustLoss::None;
          o.fit.threads = threads;
          o.fit.parameter_correction = correct == 1;
          const Result r = fit_point_cloud(cloud, o);
          dev[correct] = truth(r.fit, shape);
          seconds = r.seconds;
        }
        std::printf("%-8s %3dx%-4d %-9s %9.4f / %-8.3f %9.4f / %-8.3f %8.2f\n", name.c_str(), net, net,
                    knots == KnotPlacement::Adaptive ? "adaptive" : "uniform", dev[0].rms_mm, dev[0].max_mm,
                    dev[1].rms_mm, dev[1].max_mm, seconds);
      }
    }
  }
  }
  return 0;
}
