// The point uncertainty (Schur complement on the cameras) against Ceres' own covariance
// estimation (ceres::Covariance, sparse QR) of the same problem, for each kind of datum.
#include <gtest/gtest.h>
#include <ceres/covariance.h>
#include <Eigen/Eigenvalues>

#include "triangulate/covariance.hpp"
#include "triangulate/reconstruct.hpp"
#include "triangulate/test_scene.hpp"

namespace photomill::triangulate {
namespace {

enum class Kind { FixedControl, WeightedControl, ScaleBars, Intrinsics };

struct CovCase {
  const char* name;
  Kind kind;
};

void PrintTo(const CovCase& c, std::ostream* os) { *os << c.name; }

class CovarianceReference : public ::testing::TestWithParam<CovCase> {};

TEST_P(CovarianceReference, MatchesCeresCovariance) {
  const Kind kind = GetParam().kind;
  test::SceneOptions so;
  so.views = 5;
  so.plate_points_x = 5;
  so.plate_points_y = 4;
  so.part_points_x = 4;
  so.part_points_y = 3;
  so.noise_px = 0.2;
  const test::SceneTruth truth = test::make_scene(so);
  ReconstructInput in;
  in.tracks = truth.tracks;
  in.camera = truth.camera;
  ReconstructOptions o;
  o.outliers.rounds = 0;
  o.bundle.loss = LossKind::Trivial;
  if (kind == Kind::FixedControl || kind == Kind::WeightedControl || kind == Kind::Intrinsics) {
    in.control_points = truth.plate_points;
    if (kind == Kind::WeightedControl) {
      for (auto& p : in.control_points) p.sigma_mm = 0.05;
    }
  } else if (kind == Kind::ScaleBars) {
    const auto& p = truth.part_points;
    in.scale_bars = {{p[0].point_id, p[11].point_id, (p[0].xyz_mm - p[11].xyz_mm).norm(), 0.01},
                     {p[3].point_id, p[8].point_id, (p[3].xyz_mm - p[8].xyz_mm).norm(), 0.02}};
  }
  if (kind == Kind::Intrinsics) o.bundle.refine_intrinsics = IntrinsicsRefinement::FocalPrincipalPoint;
  Reconstruction r = reconstruct(in, o);

  const BundleSetup& setup = r.setup;  // the final adjustment's datum, gauge and sigmas
  CovarianceOptions co;
  const PointUncertainty mine = point_uncertainty(r.scene, setup, o.bundle, co);
  ASSERT_EQ(to_string(mine.method), std::string("full_covariance"));

  ceres::Problem problem;
  BundleSummary unused;
  build_problem(r.scene, setup, o.bundle, problem, unused);
  ceres::Covariance::Options copt;
  // Sparse QR: the gauge is fixed, so J has full column rank. (Not DENSE_SVD: its Eigen BDCSVD
  // inside Debian's static libceres trips AddressSanitizer with a bad free.)
  copt.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance covariance(copt);
  std::vector<std::pair<const double*, const double*>> blocks;
  std::vector<std::size_t> tracks;
  for (std::size_t t = 0; t < r.scene.tracks.size(); ++t) {
    if (!r.in_result[t] || !problem.HasParameterBlock(r.scene.tracks[t].xyz_mm.data())) continue;
    if (problem.IsParameterBlockConstant(r.scene.tracks[t].xyz_mm.data())) continue;
    blocks.push_back({r.scene.tracks[t].xyz_mm.data(), r.scene.tracks[t].xyz_mm.data()});
    tracks.push_back(t);
  }
  ASSERT_FALSE(tracks.empty());
  ASSERT_TRUE(covariance.Compute(blocks, &problem));
  for (std::size_t k = 0; k < tracks.size(); ++k) {
    double c[9];
    ASSERT_TRUE(covariance.GetCovarianceBlock(blocks[k].first, blocks[k].second, c));
    // The whole 3x3 block, and sigma_mm its largest axis (covariance.hpp).
    const Eigen::Matrix3d ceres_cov = mine.variance_factor * Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(c);
    const Eigen::Matrix3d& cov = mine.covariance_mm2[tracks[k]];
    EXPECT_LE((cov - ceres_cov).norm(), 1e-6 * ceres_cov.norm()) << "track " << r.scene.tracks[tracks[k]].id;
    const double expected = std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(ceres_cov).eigenvalues().maxCoeff());
    EXPECT_NEAR(mine.sigma_mm[tracks[k]], expected, 1e-6 * expected) << "track " << r.scene.tracks[tracks[k]].id;
    EXPECT_GE(mine.sigma_mm[tracks[k]], std::sqrt(ceres_cov.trace() / 3));
  }
}

INSTANTIATE_TEST_SUITE_P(Triangulate, CovarianceReference,
                         ::testing::Values(CovCase{"fixed_control", Kind::FixedControl},
                                           CovCase{"weighted_control", Kind::WeightedControl},
                                           CovCase{"scale_bars", Kind::ScaleBars},
                                           CovCase{"intrinsics", Kind::Intrinsics}));

}  // namespace
}  // namespace photomill::triangulate
