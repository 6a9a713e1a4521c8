// Steps 2 and 3 of the paper's section 5: the forward step between consecutive cutter-contact
// points from the chord tolerance e, and its conversion to a parameter step along the pass.
// The step is proposed from the curvature and then checked on the actual sub-curve: the chord
// must stay within e of the surface everywhere between the two CC points, and the straight move
// of the ball between the two CL points must not dip into the surface by more than the gouge
// tolerance. Output: the CL points of one pass interval.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "toolpath/cutter.hpp"
#include "toolpath/iso_passes.hpp"

namespace photomill::toolpath {

// Step 2: the longest chord whose sagitta on a circle of radius rho is at most `tol`:
//   L = 2 sqrt(tol (2 rho - tol))   (the chordal-deviation formula; rho = +inf gives +inf).
double chord_length_for_tolerance(double radius_mm, double tol_mm);

// Step 3: a forward step of L mm as a parameter step at speed |C'(t)| mm per parameter unit:
//   dt = L / |C'(t)|   (first order; the check below makes it exact where it matters).
double forward_param_step(double length_mm, const Eigen::Vector3d& tangent);

// Distance from point p to the segment [a, b].
double distance_to_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Largest value of f over (t0, t1), f sampled densely: `samples` evenly spaced interior points,
// then golden-section search around the best one until the bracket is 1e-6 of the interval.
// (Dense sampling finds which bump is largest - an S-shaped sub-curve has two - and the search
// pins its top; the midpoint alone misses both asymmetric and double bumps.)
struct SubcurveMax {
  double value = 0;
  double t = 0;
};
SubcurveMax max_over_subcurve(const std::function<double(double)>& f, double t0, double t1, int samples = 8);

// The chord error of a segment: max over t in (t0, t1) of the distance of C(t) from the chord
// [C(t0), C(t1)] (the paper's deviation e).
SubcurveMax chord_deviation(const IsoCurve& curve, double t0, double t1, int samples = 8);

// How deep the ball (radius r = R + a) moving straight from centre c0 to centre c1 reaches
// into the surface along the CC sub-curve: max over t of r - |C(t) - [c0, c1]| (negative: clear).
SubcurveMax ball_penetration(const IsoCurve& curve, double t0, double t1, const Eigen::Vector3d& c0,
                             const Eigen::Vector3d& c1, double ball_radius_mm, int samples = 8);

struct ForwardStepOptions {
  double chord_tol_mm = 0.005;    // e
  double gouge_tol_mm = 0.0005;   // deepest dip of a straight move into the surface
  double max_step_mm = 2;         // longest forward step, even on flat ground
  double min_step_mm = 1e-5;      // a shorter required step is a geometry error (a kink)
  // The proposal aims at this fraction of each tolerance, so that most proposals pass the check.
  double aim = 0.8;
  // Shorten steps until the ball's straight moves stay within gouge_tol_mm. Off when gouges are
  // only reported (no lift): then segments that touch a gouge point are not held to it.
  bool enforce_gouge = true;
  // Work limit: every CL point computed (each forward-step proposal, kept or rejected) of all
  // intervals marched with these options, in parallel too, is counted in `*points_taken` (when
  // set, else per interval); more than `max_points` stops the march with a GeometryError naming toolpath's
  // --max-cl-points. Neither endless points nor a step shortened for ever outlive it.
  std::atomic<std::size_t>* points_taken = nullptr;
  std::size_t max_points = 20'000'000;
};

// The CC/CL points of one pass interval [t0, t1] (both ends included, in the order given: t1 may
// be below t0 for a reversed pass). `locate` turns a PassFrame into its CL point (cc_to_cl).
// Where an end of a segment was lifted out of a gouge the ball no longer rests on the CC curve;
// there the move between the two ball centres is kept below sqrt(8 r tol) (see the .cpp).
// Also returns the largest chord error and ball penetration accepted.
struct MarchResult {
  std::vector<CutterLocation> points;
  std::vector<double> ts;           // parameter of each point
  double max_chord_error_mm = 0;
  double max_penetration_mm = -1e300;
  int rejected_steps = 0;           // proposals that failed the check and were shortened
};
MarchResult march_interval(const IsoCurve& curve, double t0, double t1, const ForwardStepOptions& options,
                           double ball_radius_mm,
                           const std::function<CutterLocation(const PassFrame&)>& locate);

}  // namespace photomill::toolpath
