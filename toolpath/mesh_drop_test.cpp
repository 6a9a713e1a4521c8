// The mesh drop cutter: closed forms on a flat and a tilted square (facet), beside them (edge,
// corner) and on a spike (vertex); a tessellated sphere against the analytic ball-on-sphere height
// within the tessellation's deflection; random meshes against a brute force over single triangles
// and against a dense sampling of every triangle; bad input; concurrent queries; a speed sanity.
#include "toolpath/mesh_drop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "formats/error.hpp"

namespace photomill::toolpath {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The square [x0, x1] x [y0, y1] as two triangles, heights from z(x, y).
TriangleMesh square(double x0, double y0, double x1, double y1, const std::function<double(double, double)>& z) {
  TriangleMesh m;
  m.vertices = {{x0, y0, z(x0, y0)}, {x1, y0, z(x1, y0)}, {x1, y1, z(x1, y1)}, {x0, y1, z(x0, y1)}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

// f(q) = q_z + sqrt(r^2 - |q_xy - p|^2) for a point under the ball, else -inf: the definition.
double ball_over(const Eigen::Vector3d& q, const Eigen::Vector2d& p, double r) {
  const double d2 = (q.head<2>() - p).squaredNorm();
  return d2 <= r * r ? q.z() + std::sqrt(r * r - d2) : -kInf;
}

// Largest f over a dense sampling of the triangle (a, b, c), at points a + u (b - a) + v (c - a):
// a barycentric grid of step 1/64 (its edges and corners included), then a pattern search from
// its best sample (steps +-u, +-v, +-(u - v), which follow the triangle's sides, halved whenever
// none of them climbs, down to 1e-12), since f is concave over the triangle. Every sample is a
// point of the triangle, so the result can never exceed the true maximum.
double sampled_max(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   const Eigen::Vector2d& p, double r) {
  const auto f_at = [&](double& u, double& v) {
    u = std::max(u, 0.0);
    v = std::max(v, 0.0);
    if (u + v > 1) {
      const double s = u + v;
      u /= s;
      v /= s;
    }
    return ball_over(a + u * (b - a) + v * (c - a), p, r);
  };
  double best = -kInf, bu = 0, bv = 0;
  constexpr int kN = 64;
  for (int i = 0; i <= kN; ++i) {
    for (int j = 0; i + j <= kN; ++j) {
      double u = static_cast<double>(i) / kN, v = static_cast<double>(j) / kN;
      const double f = f_at(u, v);
      if (f > best) best = f, bu = u, bv = v;
    }
  }
  if (best == -kInf) return best;
  constexpr double kDirs[6][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, -1}, {-1, 1}};
  double step = 1.0 / kN;
  for (int it = 0; it < 100000 && step > 1e-12; ++it) {
    bool climbed = false;
    for (const auto& d : kDirs) {
      double u = bu + step * d[0], v = bv + step * d[1];
      const double f = f_at(u, v);
      if (f > best) best = f, bu = u, bv = v, climbed = true;
    }
    if (!climbed) step /= 2;
  }
  return best;
}

double sampled_mesh_max(const TriangleMesh& m, const Eigen::Vector2d& p, double r) {
  double best = -kInf;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3d& a = m.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3d& b = m.vertices[static_cast<std::size_t>(t[1])];
    const Eigen::Vector3d& c = m.vertices[static_cast<std::size_t>(t[2])];
    const double lo_x = std::min({a.x(), b.x(), c.x()}), hi_x = std::max({a.x(), b.x(), c.x()});
    const double lo_y = std::min({a.y(), b.y(), c.y()}), hi_y = std::max({a.y(), b.y(), c.y()});
    if (p.x() < lo_x - r || p.x() > hi_x + r || p.y() < lo_y - r || p.y() > hi_y + r) continue;
    best = std::max(best, sampled_max(a, b, c, p, r));
  }
  return best;
}

TEST(MeshDrop, FlatSquareInsideIsExact) {
  const TriangleMesh m = square(0, 0, 10, 10, [](double, double) { return 5.0; });
  for (double r : {0.5, 2.5, 3.0}) {
    const MeshDropCutter drop(m, r);
    EXPECT_EQ(drop.ball_radius_mm(), r);
    EXPECT_EQ(drop.triangle_count(), 2u);
    EXPECT_EQ(drop.top_z(), 5.0);
    EXPECT_EQ(drop.min_xy(), Eigen::Vector2d(0, 0));
    EXPECT_EQ(drop.max_xy(), Eigen::Vector2d(10, 10));
    // Anywhere over the square (its corners, edges and the diagonal between the two triangles
    // included) the ball rests on the facet: 5 + r, exactly.
    for (const Eigen::Vector2d& xy : {Eigen::Vector2d(5, 5), Eigen::Vector2d(0.1, 9.9), Eigen::Vector2d(3.3, 3.3),
                                     Eigen::Vector2d(7.77, 2.01), Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 4),
                                     Eigen::Vector2d(6.5, 10)}) {
      EXPECT_EQ(drop.centre_z(xy), 5 + r) << "r " << r << " at " << xy.transpose();
    }
  }
}

TEST(MeshDrop, BesideTheSquareTheEdgeOrTheCornerDecides) {
  const TriangleMesh m = square(0, 0, 10, 10, [](double, double) { return 5.0; });
  const double r = 3;
  const MeshDropCutter drop(m, r);
  for (double d : {0.01, 1.0, 2.9}) {
    for (double along : {0.5, 5.0, 9.5}) {
      // Beyond each of the four edges: the edge at horizontal distance d.
      const double edge = 5 + std::sqrt(r * r - d * d);
      EXPECT_NEAR(drop.centre_z({10 + d, along}), edge, 1e-12);
      EXPECT_NEAR(drop.centre_z({-d, along}), edge, 1e-12);
      EXPECT_NEAR(drop.centre_z({along, 10 + d}), edge, 1e-12);
      EXPECT_NEAR(drop.centre_z({along, -d}), edge, 1e-12);
    }
  }
  // Beyond a corner: the corner.
  for (const Eigen::Vector2d& off : {Eigen::Vector2d(0.5, 0.5), Eigen::Vector2d(2.0, 1.0), Eigen::Vector2d(0.1, 2.9)}) {
    const double corner = 5 + std::sqrt(r * r - off.squaredNorm());
    EXPECT_NEAR(drop.centre_z(Eigen::Vector2d(10, 10) + off), corner, 1e-12);
    EXPECT_NEAR(drop.centre_z(Eigen::Vector2d(0, 0) - off), corner, 1e-12);
    EXPECT_NEAR(drop.centre_z(Eigen::Vector2d(10 + off.x(), -off.y())), corner, 1e-12);
  }
  // Out of reach: no point within r.
  EXPECT_EQ(drop.centre_z({13.01, 5}), -kInf);
  EXPECT_EQ(drop.centre_z({12.2, 12.2}), -kInf);  // 3.11 from the corner
  EXPECT_EQ(drop.centre_z({1000, -1000}), -kInf);
  EXPECT_TRUE(std::isnan(drop.centre_z({std::nan(""), 5})));
}

TEST(MeshDrop, TiltedPlaneIsTheFacetContactAndItsEdge) {
  // z = 2 + a x + b y over [0, 100]^2; upward unit normal n = (-a, -b, 1) / sqrt(1 + a^2 + b^2).
  const double a = 0.3, b = -0.4, r = 3;
  const auto plane = [&](double x, double y) { return 2 + a * x + b * y; };
  const TriangleMesh m = square(0, 0, 100, 100, plane);
  const MeshDropCutter drop(m, r);
  const double k = std::sqrt(1 + a * a + b * b);
  const Eigen::Vector3d n = Eigen::Vector3d(-a, -b, 1) / k;
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(20, 30), Eigen::Vector2d(50.5, 70.25), Eigen::Vector2d(80, 10),
                                   Eigen::Vector2d(1, 99)}) {
    const double c = drop.centre_z(xy);
    // Closed form: the centre lies at distance r from the plane along n, z_plane(p) + r / n_z.
    EXPECT_NEAR(c, plane(xy.x(), xy.y()) + r * k, 1e-12) << xy.transpose();
    // Independently: the distance of the centre from the plane is r...
    const Eigen::Vector3d centre(xy.x(), xy.y(), c);
    EXPECT_NEAR((centre - Eigen::Vector3d(0, 0, plane(0, 0))).dot(n), r, 1e-12);
    // ... and a dense sampling of the plane under the ball finds nothing higher, and something
    // within its sampling error.
    double sampled = -kInf;
    for (double dx = -r; dx <= r; dx += 0.01) {
      for (double dy = -r; dy <= r; dy += 0.01) {
        const double x = xy.x() + dx, y = xy.y() + dy;
        if (x < 0 || x > 100 || y < 0 || y > 100) continue;
        sampled = std::max(sampled, ball_over({x, y, plane(x, y)}, xy, r));
      }
    }
    EXPECT_LE(sampled, c + 1e-9);
    EXPECT_GT(sampled, c - 1e-4);
  }
  // Near the edge x = 100 the facet contact (uphill in x, 0.8 mm from the ball's axis) is off the
  // square: the ball rests on that edge. In the vertical plane x = 100, s = y, slope m = b:
  // h = 0.2, rho = sqrt(r^2 - h^2), centre = z_line(s_foot) + rho sqrt(1 + m^2).
  const Eigen::Vector2d xy(99.8, 50);
  const double rho = std::sqrt(r * r - 0.2 * 0.2);
  const double edge = plane(100, 50) + rho * std::sqrt(1 + b * b);
  EXPECT_NEAR(drop.centre_z(xy), edge, 1e-12);
  EXPECT_LT(edge, plane(xy.x(), xy.y()) + r * k) << "the edge is below the (missed) facet contact";
  EXPECT_NEAR(sampled_mesh_max(m, xy, r), edge, 1e-6);
}

TEST(MeshDrop, SpikeVertexHoldsTheBall) {
  // A needle: apex (0, 0, 10) on a 1 x 1 base at z = 0 (four sides of slope 20 and the base).
  TriangleMesh m;
  m.vertices = {{-0.5, -0.5, 0}, {0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.5, 0}, {0, 0, 10}};
  m.triangles = {{0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}, {0, 2, 1}, {0, 3, 2}};
  const double r = 3;
  const MeshDropCutter drop(m, r);
  EXPECT_EQ(drop.top_z(), 10.0);
  for (double d : {0.0, 0.3, 1.0, 2.0, 2.9}) {
    for (double angle : {0.0, 0.7, 2.0, 4.4}) {
      const Eigen::Vector2d xy(d * std::cos(angle), d * std::sin(angle));
      EXPECT_NEAR(drop.centre_z(xy), 10 + std::sqrt(r * r - d * d), 1e-12) << xy.transpose();
    }
  }
  EXPECT_EQ(drop.centre_z({0, 0}), 10 + r);
  EXPECT_EQ(drop.centre_z({3.0, 3.0}), -kInf);  // 3.54 from the base's corner
}

TEST(MeshDrop, TessellatedSphereWithinItsDeflection) {
  // A cap (polar angle <= 70 deg) of the sphere |x| = R, vertices on the sphere: 40 rings of 80.
  const double R = 20, r = 3;
  const int rings = 40, around = 80;
  const double cap = 70.0 / 180 * std::numbers::pi;
  TriangleMesh m;
  m.vertices.push_back({0, 0, R});
  for (int i = 1; i <= rings; ++i) {
    const double th = cap * i / rings;
    for (int j = 0; j < around; ++j) {
      const double ph = 2 * std::numbers::pi * j / around;
      m.vertices.push_back({R * std::sin(th) * std::cos(ph), R * std::sin(th) * std::sin(ph), R * std::cos(th)});
    }
  }
  const auto at = [&](int i, int j) { return i == 0 ? 0 : 1 + (i - 1) * around + (j % around); };
  for (int j = 0; j < around; ++j) m.triangles.push_back({at(0, 0), at(1, j), at(1, j + 1)});
  for (int i = 1; i < rings; ++i) {
    for (int j = 0; j < around; ++j) {
      m.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  const MeshDropCutter drop(m, r);
  // Deflection: every mesh point is at least R' = the smallest distance of a facet's plane from
  // the centre, so along a vertical at horizontal radius rho the mesh lies between the spheres
  // R' and R, at most dz = sqrt(R^2 - rho^2) - sqrt(R'^2 - rho^2) below the sphere. The drop
  // height over a height field moves by no more than the field does: over the sphere it is
  // sqrt((R + r)^2 - |p|^2), so the mesh's lies in [that - dz, that] (queries |p| <= 12, their
  // balls reach rho <= 15, their contacts at polar angles <= 32 deg, inside the cap).
  double inner = R;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3d& a = m.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3d nrm = (m.vertices[static_cast<std::size_t>(t[1])] - a)
                                    .cross(m.vertices[static_cast<std::size_t>(t[2])] - a)
                                    .normalized();
    inner = std::min(inner, std::abs(nrm.dot(a)));
  }
  const double rho_max = 15;
  const double dz = std::sqrt(R * R - rho_max * rho_max) - std::sqrt(inner * inner - rho_max * rho_max);
  ASSERT_GT(dz, 0);
  ASSERT_LT(dz, 0.05) << "the tessellation is fine enough for the check to mean something";
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-12, 12);
  double worst_below = 0;
  for (int q = 0; q < 300; ++q) {
    const Eigen::Vector2d xy(U(rng), U(rng));
    if (xy.norm() > 12) continue;
    const double analytic = std::sqrt((R + r) * (R + r) - xy.squaredNorm());
    const double c = drop.centre_z(xy);
    EXPECT_LE(c, analytic + 1e-9) << xy.transpose();
    EXPECT_GE(c, analytic - dz - 1e-9) << xy.transpose();
    worst_below = std::max(worst_below, analytic - c);
  }
  EXPECT_GT(worst_below, 0) << "a polyhedron inside the sphere sits lower somewhere";
  // Straight over the pole: the ball rests on the pole's fan.
  EXPECT_LE(drop.centre_z({0, 0}), R + r);
  EXPECT_GE(drop.centre_z({0, 0}), R + r - dz);
}

// Random triangles with random heights, and degenerate ones: collinear corners, a repeated
// corner, a vertical triangle, a sliver of nearly collinear corners.
TriangleMesh random_mesh(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> centre(0, 10), off(-2.5, 2.5), height(0, 3);
  TriangleMesh m;
  for (int t = 0; t < count; ++t) {
    const Eigen::Vector2d c(centre(rng), centre(rng));
    const int base = static_cast<int>(m.vertices.size());
    for (int k = 0; k < 3; ++k) m.vertices.push_back({c.x() + off(rng), c.y() + off(rng), height(rng)});
    m.triangles.push_back({base, base + 1, base + 2});
  }
  const int base = static_cast<int>(m.vertices.size());
  m.vertices.push_back({2, 2, 4});
  m.vertices.push_back({5, 3, 3.5});
  m.vertices.push_back({8, 4, 3});      // collinear with the two before, in xy and z
  m.vertices.push_back({7, 7, 1});
  m.vertices.push_back({7, 7, 4.5});    // vertical above the one before
  m.vertices.push_back({8.5, 6, 2});
  m.triangles.push_back({base, base + 1, base + 2});      // zero area
  m.triangles.push_back({base + 3, base + 3, base + 5});  // repeated corner
  m.triangles.push_back({base + 3, base + 4, base + 5});  // vertical
  // Nearly collinear corners (0.1 is not a binary fraction: the cross product is rounding only).
  const Eigen::Vector3d a(1, 8, 3.2), d(0.1, -0.3, 0.07);
  m.vertices.push_back(a);
  m.vertices.push_back(a + 30 * d);
  m.vertices.push_back(a + 70 * d);
  m.triangles.push_back({base + 6, base + 7, base + 8});
  return m;
}

TEST(MeshDrop, RandomMeshesMatchBruteForceAndDenseSampling) {
  std::mt19937 rng(2024);
  for (int mesh = 0; mesh < 4; ++mesh) {
    const TriangleMesh m = random_mesh(rng, 30 + 20 * mesh);
    const double r = std::uniform_real_distribution<double>(0.4, 2.5)(rng);
    const MeshDropCutter drop(m, r);
    // Brute force: the same per-triangle answer, each triangle on its own (no shared buckets).
    std::vector<MeshDropCutter> singles;
    for (const auto& t : m.triangles) {
      TriangleMesh one;
      one.vertices = m.vertices;
      one.triangles = {t};
      singles.emplace_back(one, r);
    }
    std::uniform_real_distribution<double> where(-3, 13);
    int hits = 0;
    for (int q = 0; q < 40; ++q) {
      const Eigen::Vector2d xy(where(rng), where(rng));
      const double c = drop.centre_z(xy);
      double brute = -kInf;
      for (const MeshDropCutter& s : singles) brute = std::max(brute, s.centre_z(xy));
      EXPECT_EQ(c, brute) << "mesh " << mesh << " at " << xy.transpose();
      const double sampled = sampled_mesh_max(m, xy, r);
      if (sampled == -kInf) {
        EXPECT_EQ(c, -kInf) << "mesh " << mesh << " at " << xy.transpose();
        continue;
      }
      ++hits;
      EXPECT_LE(sampled, c + 1e-9) << "a mesh point inside the ball: mesh " << mesh << " at " << xy.transpose();
      EXPECT_GE(sampled, c - 1e-9) << "the ball floats: mesh " << mesh << " at " << xy.transpose();
    }
    EXPECT_GT(hits, 20);
  }
}

TEST(MeshDrop, BadInputThrows) {
  const TriangleMesh good = square(0, 0, 1, 1, [](double, double) { return 0.0; });
  EXPECT_NO_THROW(MeshDropCutter(good, 1.0));
  TriangleMesh nan_vertex = good;
  nan_vertex.vertices[2].z() = std::nan("");
  EXPECT_THROW(MeshDropCutter(nan_vertex, 1.0), GeometryError);
  TriangleMesh inf_vertex = good;
  inf_vertex.vertices[1].x() = kInf;
  EXPECT_THROW(MeshDropCutter(inf_vertex, 1.0), GeometryError);
  TriangleMesh bad_index = good;
  bad_index.triangles[1][2] = 4;
  EXPECT_THROW(MeshDropCutter(bad_index, 1.0), GeometryError);
  bad_index.triangles[1][2] = -1;
  EXPECT_THROW(MeshDropCutter(bad_index, 1.0), GeometryError);
  for (double r : {0.0, -1.0, std::nan(""), kInf}) EXPECT_THROW(MeshDropCutter(good, r), GeometryError) << r;
  TriangleMesh empty = good;
  empty.triangles.clear();
  EXPECT_THROW(MeshDropCutter(empty, 1.0), GeometryError);
  EXPECT_THROW(MeshDropCutter(TriangleMesh{}, 1.0), GeometryError);
}

TEST(MeshDrop, RefusesAGridBeyondTheMemoryBound) {
  // 20000 large triangles all over the same box: each would go into every bucket, 4e8 in all.
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1000, 0, 0}, {0, 1000, 0}};
  m.triangles.assign(20000, {0, 1, 2});
  try {
    const MeshDropCutter drop(m, 0.5);
    ADD_FAILURE() << "no error";
  } catch (const GeometryError& e) {
    EXPECT_NE(std::string(e.what()).find("registrations"), std::string::npos) << e.what();
  }
  m.triangles.resize(200);
  EXPECT_NO_THROW(MeshDropCutter(m, 0.5));
}

// A 100 x 100 mm height field of 2 x 99^2 = 19602 triangles: z = 10 + 3 sin(x / 7) cos(y / 11).
TriangleMesh wave_mesh() {
  TriangleMesh m;
  const int n = 100;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = i * 100.0 / (n - 1), y = j * 100.0 / (n - 1);
      m.vertices.push_back({x, y, 10 + 3 * std::sin(x / 7) * std::cos(y / 11)});
    }
  }
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      const int v = i * n + j;
      m.triangles.push_back({v, v + n, v + n + 1});
      m.triangles.push_back({v, v + n + 1, v + 1});
    }
  }
  return m;
}

TEST(MeshDrop, ConcurrentQueriesAgreeWithSerialOnes) {
  const TriangleMesh m = wave_mesh();
  const MeshDropCutter drop(m, 2.0);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-5, 105);
  std::vector<Eigen::Vector2d> xy(4096);  // a power of two: k -> k (2t + 1) + 97 t mod 4096 is a permutation
  for (auto& p : xy) p = {U(rng), U(rng)};
  std::vector<double> serial(xy.size());
  for (std::size_t i = 0; i < xy.size(); ++i) serial[i] = drop.centre_z(xy[i]);
  constexpr int kThreads = 4;
  std::vector<std::vector<double>> parallel(kThreads, std::vector<double>(xy.size()));
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      // Each thread in its own order, so that they interleave on the same buckets.
      for (std::size_t k = 0; k < xy.size(); ++k) {
        const std::size_t i = (k * static_cast<std::size_t>(2 * t + 1) + static_cast<std::size_t>(t) * 97) % xy.size();
        parallel[static_cast<std::size_t>(t)][i] = drop.centre_z(xy[i]);
      }
    });
  }
  for (auto& th : threads) th.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(parallel[static_cast<std::size_t>(t)], serial) << "thread " << t;
}

TEST(MeshDrop, SpeedSanityOnTwentyThousandTriangles) {
  // Not a timed assertion: the times go to the test's XML properties (--gtest_output=xml).
  const TriangleMesh m = wave_mesh();
  const auto t0 = std::chrono::steady_clock::now();
  const MeshDropCutter drop(m, 3.0);
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_EQ(drop.triangle_count(), 19602u);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(0, 100);
  constexpr int kQueries = 20000;
  std::vector<Eigen::Vector2d> xy(kQueries);
  for (auto& p : xy) p = {U(rng), U(rng)};
  std::vector<double> z(kQueries);
  const auto t2 = std::chrono::steady_clock::now();
  for (int i = 0; i < kQueries; ++i) z[static_cast<std::size_t>(i)] = drop.centre_z(xy[static_cast<std::size_t>(i)]);
  const auto t3 = std::chrono::steady_clock::now();
  // Each answer is at least what the nearest vertex alone gives, and at most top + r.
  for (int i = 0; i < kQueries; ++i) {
    const Eigen::Vector2d& p = xy[static_cast<std::size_t>(i)];
    const int gi = static_cast<int>(std::lround(p.x() * 99 / 100)), gj = static_cast<int>(std::lround(p.y() * 99 / 100));
    const double vertex = ball_over(m.vertices[static_cast<std::size_t>(gi * 100 + gj)], p, 3.0);
    ASSERT_GE(z[static_cast<std::size_t>(i)], vertex) << p.transpose();
    ASSERT_LE(z[static_cast<std::size_t>(i)], drop.top_z() + 3.0) << p.transpose();
  }
  using us = std::chrono::duration<double, std::micro>;
  RecordProperty("build_ms", std::to_string(us(t1 - t0).count() / 1000));
  RecordProperty("us_per_query", std::to_string(us(t3 - t2).count() / kQueries));
}

}  // namespace
}  // namespace photomill::toolpath
